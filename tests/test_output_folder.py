"""The output folder: made with its parents, refused (naming the path) when it is a file.

A run's folder: temporaries renamed on success, a lock naming the run that holds it, taken over
from a dead one, and an earlier run replaced only with overwrite.
"""

import os
import subprocess
import sys

import pytest

from maskless.diagrams.output_folder import (
    LOCK_NAME,
    RunFolder,
    output_file,
    output_folder,
    partial_name,
)
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


def test_a_run_writes_temporaries_and_renames_them_on_success(tmp_path):
    with RunFolder(tmp_path / "run", ["run.mcap", "run.png"]) as folder:
        assert folder.temporary("run.mcap") == tmp_path / "run" / "run.partial.mcap"
        folder.temporary("run.mcap").write_text("data")
        assert not folder.final("run.mcap").exists()
    assert sorted(p.name for p in folder.path.iterdir()) == ["run.mcap"]  # lock gone too
    assert folder.final("run.mcap").read_text() == "data"


def test_a_failed_run_leaves_its_temporaries_named_and_no_final_file(tmp_path):
    with pytest.raises(RuntimeError) as failure:
        with RunFolder(tmp_path / "run", ["run.mcap", "run.png"]) as folder:
            folder.temporary("run.mcap").write_text("half")
            raise RuntimeError("stopped")
    assert sorted(p.name for p in folder.path.iterdir()) == ["run.partial.mcap"]
    assert failure.value.__notes__ == [f"what the run wrote is in {folder.temporary('run.mcap')}"]
    # A run that wrote nothing leaves no folder it made.
    with pytest.raises(RuntimeError):
        with RunFolder(tmp_path / "empty", ["run.mcap"]):
            raise RuntimeError("stopped")
    assert not (tmp_path / "empty").exists()


def test_an_earlier_run_is_replaced_only_with_overwrite(tmp_path):
    names = ["run.mcap", "run.png", "frames.png"]
    for earlier in ("run.png", "frames.partial.png"):  # a finished run, or a stopped one's
        (tmp_path / earlier).write_text("earlier")
        with pytest.raises(ConfigError, match=f"{earlier}: .*give --overwrite"):
            RunFolder(tmp_path, names).check()
        with pytest.raises(ConfigError, match=f"{earlier}: .*give --overwrite"):
            RunFolder(tmp_path, names).claim()
        (tmp_path / earlier).unlink()
    (tmp_path / "frames.partial.png").write_text("earlier")
    (tmp_path / "frames.png").write_text("earlier")
    with RunFolder(tmp_path, names, overwrite=True) as folder:
        assert not folder.temporary("frames.png").exists()  # a stopped run's is cleared
        folder.temporary("run.mcap").write_text("new")
    # None of the earlier run's files stays beside the new one's.
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.mcap"]


def test_a_folder_in_use_is_refused_naming_the_other_pid(tmp_path):
    with RunFolder(tmp_path, ["run.mcap"]):
        assert (tmp_path / LOCK_NAME).read_text() == f"{os.getpid()}\n"
        message = f"{tmp_path}: in use by another run \\(pid {os.getpid()}\\)"
        with pytest.raises(ConfigError, match=message):
            RunFolder(tmp_path, ["run.mcap"]).claim()
        with pytest.raises(ConfigError, match=message):
            RunFolder(tmp_path, ["run.mcap"]).check()
    RunFolder(tmp_path, ["run.mcap"]).claim()  # free again


def test_a_run_in_another_process_holds_the_folder_until_it_ends(tmp_path):
    claim = (
        "import sys, time; from maskless.diagrams.output_folder import RunFolder; "
        f"RunFolder({str(tmp_path)!r}, ['run.mcap']).claim(); print('claimed', flush=True); "
        "time.sleep(60)"
    )
    other = subprocess.Popen([sys.executable, "-c", claim], stdout=subprocess.PIPE, text=True)
    try:
        assert other.stdout.readline() == "claimed\n"
        with pytest.raises(ConfigError, match=f"in use by another run \\(pid {other.pid}\\)"):
            RunFolder(tmp_path, ["run.mcap"]).claim()
    finally:
        other.kill()
        other.wait()
        other.stdout.close()
    # Killed, it left its lock file; the kernel dropped the lock, so the next run takes it over.
    assert (tmp_path / LOCK_NAME).read_text() == f"{other.pid}\n"
    with RunFolder(tmp_path, ["run.mcap"]):
        assert (tmp_path / LOCK_NAME).read_text() == f"{os.getpid()}\n"


def test_check_makes_nothing(tmp_path):
    RunFolder(tmp_path / "a" / "b", ["run.mcap"]).check()
    assert not (tmp_path / "a").exists()
    (tmp_path / "file").write_text("")
    with pytest.raises(ConfigError, match="file: expected a folder to write into, found a file"):
        RunFolder(tmp_path / "file", ["run.mcap"]).check()


def test_partial_names_keep_the_suffix():
    assert partial_name("run.mcap") == "run.partial.mcap"
    assert partial_name("frames.png") == "frames.partial.png"
