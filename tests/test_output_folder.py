"""The output folder: made with its parents, refused (naming the path) when it is a file."""

import pytest

from maskless.diagrams.output_folder import output_file, output_folder
from maskless.errors import ConfigError


def test_a_missing_folder_is_made_with_its_parents(tmp_path):
    folder = output_folder(tmp_path / "a" / "b")
    assert folder.is_dir() and folder == tmp_path / "a" / "b"
    assert output_folder(folder) == folder  # an existing folder is fine


def test_a_file_in_the_way_is_named(tmp_path):
    (tmp_path / "taken").write_text("")
    with pytest.raises(ConfigError, match="taken: expected a folder to write into, found a file"):
        output_folder(tmp_path / "taken")
    with pytest.raises(ConfigError, match="taken/below"):
        output_folder(tmp_path / "taken" / "below")


def test_a_file_gets_its_folder_made(tmp_path):
    path = output_file(tmp_path / "new" / "run.mcap")
    assert path == tmp_path / "new" / "run.mcap" and path.parent.is_dir() and not path.exists()
