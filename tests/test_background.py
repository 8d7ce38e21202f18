import sys

import pytest

from maskless.diagrams.background import BackgroundTask


def write_text(path, text):
    path.write_text(text)


def test_task_runs_and_its_result_is_there_after_wait(tmp_path):
    target = tmp_path / "out.txt"
    task = BackgroundTask("writing out.txt", write_text, target, "done")
    task.wait()
    assert target.read_text() == "done"


def test_a_failing_task_is_reported_by_wait():
    task = BackgroundTask("exiting with 3", sys.exit, 3)
    with pytest.raises(RuntimeError, match="exiting with 3 failed.*exit code 3"):
        task.wait()
