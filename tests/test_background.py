"""Forked workers: they run, receive in order, and wait reports failures."""

import sys
from functools import partial

import pytest

from maskless.diagrams.background import Worker, serve_calls


def write_text(path, text):
    path.write_text(text)


def record_warm_up(path):
    path.write_text("warm")


def write_after_warm_up(marker, path, text):
    # The work sees the warm-up's result: it ran first, in the same child.
    path.write_text(marker.read_text() + " " + text)


def test_a_call_worker_warms_up_before_the_calls_arrive(tmp_path):
    marker, target = tmp_path / "warm.txt", tmp_path / "out.txt"
    worker = Worker("writing out.txt", serve_calls, partial(record_warm_up, marker))
    worker.send((write_after_warm_up, (marker, target), {"text": "done"}))
    worker.wait()
    assert target.read_text() == "warm done"


def collect(connection, path):
    received = []
    while (message := connection.recv()) is not None:
        received.append(message)
    path.write_text(repr(received))


def test_a_worker_receives_what_is_sent_in_order_then_none(tmp_path):
    target = tmp_path / "out.txt"
    worker = Worker("collecting", collect, target)
    # A second worker forked meanwhile holds a copy of the first one's pipe: the end marker,
    # not the pipe's end, must stop the first.
    other = Worker("idle", serve_calls, lambda: None)
    for message in (1, "two", [3.0]):
        worker.send(message)
    worker.wait()
    other.wait()
    assert target.read_text() == "[1, 'two', [3.0]]"


def test_a_failing_worker_is_reported_by_wait():
    worker = Worker("exiting with 4", serve_calls, lambda: None)
    worker.send((sys.exit, (4,), {}))
    with pytest.raises(RuntimeError, match="exiting with 4 failed.*exit code 4"):
        worker.wait()


def test_a_worker_whose_warm_up_failed_is_reported_by_wait_not_by_send(tmp_path):
    worker = Worker("warming up", serve_calls, partial(sys.exit, 5))
    worker._child._process.join()  # the warm-up has failed before anything is sent
    worker.send((write_text, (tmp_path / "never.txt", "x"), {}))
    with pytest.raises(RuntimeError, match="warming up failed.*exit code 5"):
        worker.wait()
    assert not (tmp_path / "never.txt").exists()


def record_until_the_end(connection, path):
    received = []
    try:
        while (message := connection.recv()) is not None:
            received.append(message)
    except EOFError:
        received.append("cut")
    path.write_text(repr(received))


def test_a_stopped_worker_sees_eof_after_what_was_sent(tmp_path):
    target = tmp_path / "out.txt"
    worker = Worker("collecting", record_until_the_end, target)
    worker.send(1)
    worker.stop()
    assert target.read_text() == "[1, 'cut']"
    worker.stop()  # once is enough
    worker.wait()


def test_a_stopped_call_worker_ends_quietly_and_wait_after_it_is_a_no_op():
    worker = Worker("idle", serve_calls, lambda: None)
    worker.stop()
    worker.wait()
