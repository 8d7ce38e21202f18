"""A request names a field by the flag the user gave, else by the field's own name."""

import pytest

from maskless.diagrams.excitation_run import ExcitationRequest
from maskless.diagrams.request_labels import LabelledRequest
from maskless.errors import ConfigError


def test_a_field_is_named_by_its_label_or_its_own_name():
    request = LabelledRequest(labels={"duration_s": "--duration"})
    assert request.label("duration_s") == "--duration"
    assert request.label("amplitude_a") == "amplitude_a"


def test_labels_are_keyword_only_and_do_not_change_equality():
    plain = ExcitationRequest(duration_s=10.0)
    labelled = ExcitationRequest(duration_s=10.0, labels={"duration_s": "--duration"})
    assert plain == labelled
    with pytest.raises(ConfigError, match="^--duration -1.0: expected a positive"):
        ExcitationRequest(duration_s=-1.0, labels={"duration_s": "--duration"})
    with pytest.raises(ConfigError, match="^duration_s -1.0: expected a positive"):
        ExcitationRequest(duration_s=-1.0)
