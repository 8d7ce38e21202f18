"""Forked workers: they run, receive in order, and wait reports failures."""

import os
import subprocess
import sys
import time
from functools import partial

import pytest

from maskless.diagrams import background
from maskless.diagrams.background import Worker, serve_calls, serve_calls_at_once


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


# Long enough for a loaded machine, short enough that a failing test does not hang the suite (s).
_PATIENCE_S = 20.0


def wait_for(path, patience_s=_PATIENCE_S):
    deadline = time.monotonic() + patience_s
    while not path.exists():
        if time.monotonic() > deadline:
            raise TimeoutError(f"{path} never appeared")
        time.sleep(0.01)


def meet(mine, other):
    # Each of two calls announces itself, then waits for the other: only calls running side by
    # side both get past this.
    mine.write_text("here")
    wait_for(other)


def meet_all(mine, others):
    # As ``meet``, with every one of ``others``.
    mine.write_text("here")
    for other in others:
        wait_for(other)


def test_calls_served_at_once_run_side_by_side(tmp_path, monkeypatch):
    monkeypatch.setattr(background, "usable_cores", lambda: 2)  # even on a one-core machine
    first, second = tmp_path / "first", tmp_path / "second"
    worker = Worker("meeting", serve_calls_at_once, lambda: None)
    worker.send((meet, (first, second), {}))
    worker.send((meet, (second, first), {}))
    worker.wait()  # one after the other, the first call would time out and fail
    assert first.exists() and second.exists()


def test_three_calls_on_two_cores_all_run_at_once(tmp_path, monkeypatch):
    # `maskless identify`'s three plots: one call per core left the third to run alone after.
    monkeypatch.setattr(background, "usable_cores", lambda: 2)
    calls = [tmp_path / f"call{index}" for index in range(3)]
    worker = Worker("meeting", serve_calls_at_once, lambda: None)
    for call in calls:
        worker.send((meet_all, (call, [other for other in calls if other != call]), {}))
    worker.wait()
    assert all(call.exists() for call in calls)


def announce_and_wait(mine, release):
    mine.write_text("here")
    wait_for(release)


def test_calls_past_two_a_core_wait_for_one_to_end(tmp_path, monkeypatch):
    monkeypatch.setattr(background, "usable_cores", lambda: 1)
    first, second, third = (tmp_path / name for name in ("first", "second", "third"))
    release = tmp_path / "release"
    worker = Worker("waiting", serve_calls_at_once, lambda: None)
    worker.send((announce_and_wait, (first, release), {}))
    worker.send((announce_and_wait, (second, release), {}))
    worker.send((write_text, (third, "ran"), {}))
    wait_for(first)
    wait_for(second)
    time.sleep(0.3)  # time enough for the third call to start, were it let
    assert not third.exists()
    release.write_text("go")
    worker.wait()
    assert third.read_text() == "ran"


_WARMED: list[int] = []


def warm_up_here():
    _WARMED.append(os.getpid())


def record_warm_up_and_parent(path):
    path.write_text(f"{_WARMED} {os.getppid()}")


def test_each_call_is_a_fork_of_the_warmed_up_worker(tmp_path):
    worker = Worker("recording", serve_calls_at_once, warm_up_here)
    target = tmp_path / "out.txt"
    worker.send((record_warm_up_and_parent, (target,), {}))
    worker_pid = worker._child._process.pid
    worker.wait()
    # Warmed up once, in the worker, which is the call's parent.
    assert target.read_text() == f"[{worker_pid}] {worker_pid}"
    assert _WARMED == []  # not here, in the caller


def fail_with_value_error(path):
    raise ValueError(f"no plot for {path}")


def write_late(path):
    time.sleep(0.3)
    path.write_text("late")


def test_a_failed_call_is_reported_by_name_once_the_others_have_ended(tmp_path, capfd):
    worker = Worker("plotting", serve_calls_at_once, lambda: None)
    late = tmp_path / "late.txt"
    worker.send((fail_with_value_error, ("bad.png",), {}))
    worker.send((write_late, (late,), {}))
    with pytest.raises(RuntimeError, match="plotting failed.*exit code 1"):
        worker.wait()
    assert late.read_text() == "late"
    errors = capfd.readouterr().err
    assert "ValueError: no plot for bad.png" in errors
    assert "fail_with_value_error(bad.png) failed" in errors


def start_a_child_and_leave_it():
    subprocess.Popen([sys.executable, "-c", "pass"])  # ends at once; never waited for


def test_a_child_the_warm_up_left_behind_is_passed_over(tmp_path):
    # It ends before the call does: the wait for the call must not take it for one.
    worker = Worker("writing", serve_calls_at_once, start_a_child_and_leave_it)
    late = tmp_path / "late.txt"
    worker.send((write_late, (late,), {}))
    worker.wait()
    assert late.read_text() == "late"


def sleep_after_announcing(started, done):
    # Written under another name and renamed: a reader that sees the file sees its pid (a loaded
    # machine once read it between the file's creation and its text).
    partial = started.with_suffix(".partial")
    partial.write_text(str(os.getpid()))
    partial.rename(started)
    time.sleep(60)
    done.write_text("done")


def test_stopping_a_worker_kills_the_calls_it_runs(tmp_path):
    started, done = tmp_path / "started", tmp_path / "done"
    worker = Worker("sleeping", serve_calls_at_once, lambda: None)
    worker.send((sleep_after_announcing, (started, done), {}))
    wait_for(started)
    begun = time.monotonic()
    worker.stop()
    assert time.monotonic() - begun < _PATIENCE_S  # not the call's 60 s
    with pytest.raises(ProcessLookupError):  # killed and reaped
        os.kill(int(started.read_text()), 0)
    assert not done.exists()


def append_pid(path, tag):
    with path.open("a") as file:
        file.write(f"{tag} {os.getpid()}\n")


def test_without_fork_calls_served_at_once_run_in_order_in_the_caller(tmp_path, monkeypatch):
    monkeypatch.setattr(background, "_FORK_IS_SAFE", False)
    target = tmp_path / "out.txt"
    worker = Worker("appending", serve_calls_at_once, lambda: None)
    for tag in ("a", "b", "c"):
        worker.send((append_pid, (target, tag), {}))
    worker.wait()
    assert target.read_text() == "".join(f"{tag} {os.getpid()}\n" for tag in "abc")
