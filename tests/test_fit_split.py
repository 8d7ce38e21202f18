"""The parts of a record `maskless identify` fits and judges, and where each came from.

Given, the recording's, or the default; and the warning for a fit on a part other than the one a
recording was designed for.
"""

import pytest

from maskless.analysis.identification.records import OVERLAPPING_PARTS_WARNING
from maskless.diagrams.fit_split import (
    DEFAULT,
    DEFAULT_ESTIMATION,
    DEFAULT_VALIDATION,
    DESIGNED,
    GIVEN,
    fit_split,
    parts_of_share,
)
from maskless.errors import RecordError

DESIGNED_PARTS = {"estimation": "0:0.8", "validation": "0.8:1"}


def test_a_recording_without_a_design_is_split_as_given_or_by_default():
    split = fit_split(None, None, None, 1000)
    assert (split.estimation, split.validation) == (DEFAULT_ESTIMATION, DEFAULT_VALIDATION)
    assert (split.estimation_from, split.validation_from) == (DEFAULT, DEFAULT)
    split = fit_split(None, "0:0.5", None, 1000)
    assert (split.estimation, split.estimation_from) == ("0:0.5", GIVEN)
    assert split.warnings == ()


@pytest.mark.parametrize(
    "estimation, validation, overlap",
    [("0:0.8", "0:1", True), ("0:0.6", "0.59:1", True), ("0:600", "600:1000", False)],
)
def test_parts_that_share_samples_are_warned_not_a_holdout(estimation, validation, overlap):
    # Before, --method hammerstein judged overlapping parts unwarned ("the valve maps explain 26.1
    # points ... more" on a validation part holding the estimation part); the linear methods warned.
    split = fit_split(None, estimation, validation, 1000)
    assert (OVERLAPPING_PARTS_WARNING in split.warnings) == overlap


def test_a_designed_recording_gives_the_parts_not_given():
    split = fit_split(DESIGNED_PARTS, None, None, 1000)
    assert split.summary() == {
        "estimation": "0:0.8",
        "estimation_from": DESIGNED,
        "validation": "0.8:1",
        "validation_from": DESIGNED,
    }
    assert split.warnings == ()
    # Judging on another part leaves the fit as designed: nothing to warn.
    split = fit_split(DESIGNED_PARTS, None, "0.9:1", 1000)
    assert (split.estimation_from, split.validation, split.validation_from) == (
        DESIGNED,
        "0.9:1",
        GIVEN,
    )
    assert split.warnings == ()


@pytest.mark.parametrize("given", ["0:0.6", "0:0.9", "0.1:0.8", "0:799"])
def test_fitting_another_part_than_the_designed_one_is_warned(given):
    warning, *others = fit_split(DESIGNED_PARTS, given, None, 1000).warnings
    assert warning.startswith(f"--estimation {given} is not the part this recording was designed")
    # 0:0.9 reaches into the design's validation part 0.8:1.
    assert others == ([OVERLAPPING_PARTS_WARNING] if given == "0:0.9" else [])
    assert "(0:0.8: " in warning and "leave --estimation out" in warning


@pytest.mark.parametrize("given", ["0:0.8", "0:0.80", "0:800", "0.0:0.8"])
def test_the_designed_part_written_another_way_is_not_warned(given):
    assert fit_split(DESIGNED_PARTS, given, None, 1000).warnings == ()


def test_a_part_that_is_not_a_part_is_refused_naming_where_it_came_from():
    with pytest.raises(RecordError, match="the recording's estimation part"):
        fit_split({"estimation": "0:x"}, None, None, 1000)
    with pytest.raises(RecordError, match="--validation"):
        fit_split(DESIGNED_PARTS, None, "0.8:2", 1000)
    split = fit_split(None, "0:0.5", "0.5:1", 1000)
    assert (split.estimation_part, split.validation_part) == (slice(0, 500), slice(500, 1000))


def test_a_share_is_the_part_before_it_and_the_rest():
    assert parts_of_share(0.8) == DESIGNED_PARTS
    assert parts_of_share(0.7) == {"estimation": "0:0.7", "validation": "0.7:1"}
