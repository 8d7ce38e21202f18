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


def write_after_warm_up(marker, path, text):
    # The work sees the warm-up's result: it ran first, in the same child.
    path.write_text(marker.read_text() + " " + text)


def test_warm_worker_prepares_before_the_work_arrives(tmp_path):
    marker, target = tmp_path / "warm.txt", tmp_path / "out.txt"
    worker = WarmWorker("writing out.txt", partial(record_warm_up, marker))
    worker.submit(write_after_warm_up, marker, target, text="done")
    worker.wait()
    assert target.read_text() == "warm done"


def test_a_failing_warm_worker_is_reported_by_wait():
    worker = WarmWorker("exiting with 4", lambda: None)
    worker.submit(sys.exit, 4)
    with pytest.raises(RuntimeError, match="exiting with 4 failed.*exit code 4"):
        worker.wait()


def test_a_worker_whose_warm_up_failed_is_reported_by_wait_not_by_submit(tmp_path):
    worker = WarmWorker("warming up", partial(sys.exit, 5))
    worker._child._process.join()  # the warm-up has failed before the work is sent
    worker.submit(write_text, tmp_path / "never.txt", text="x")
    with pytest.raises(RuntimeError, match="warming up failed.*exit code 5"):
        worker.wait()
    assert not (tmp_path / "never.txt").exists()
