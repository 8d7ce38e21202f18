import sys
from functools import partial

import pytest

from maskless.diagrams.background import BackgroundTask, WarmWorker


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


def record_warm_up(path):
    path.write_text("warm")


def test_warm_worker_prepares_before_the_work_arrives(tmp_path):
    marker, target = tmp_path / "warm.txt", tmp_path / "out.txt"
    worker = WarmWorker("writing out.txt", partial(record_warm_up, marker))
    worker.submit(write_text, target, text="done")
    worker.wait()
    assert marker.read_text() == "warm" and target.read_text() == "done"


def test_a_failing_warm_worker_is_reported_by_wait():
    worker = WarmWorker("exiting with 4", lambda: None)
    worker.submit(sys.exit, 4)
    with pytest.raises(RuntimeError, match="exiting with 4 failed.*exit code 4"):
        worker.wait()
