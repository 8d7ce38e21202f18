"""Work in forked child processes while the caller goes on, to use a second core.

A ``Worker`` forks early and serves what the caller sends it later (picklable objects, through a
pipe): `maskless simulate` streams the recording to one while the loop runs, and has another
import matplotlib meanwhile (~0.35 s) and then plot; `maskless identify` has one import
matplotlib while it imports the estimators, then draw its plots side by side
(``serve_calls_at_once``). Child processes, not threads: a thread's work would hold the GIL the
simulation needs.

A worker never outlives its caller. Its ``connection.recv()`` raises EOFError once the caller is
gone (killed, even by SIGKILL: the worker polls for its parent while it waits), once the caller
calls ``stop`` (it was interrupted), or once the worker itself gets SIGTERM; a serve function
that has something to finish (a recording's footer) catches it, the others just end. Children
ignore SIGINT: a terminal's Ctrl-C reaches the whole process group, and the caller decides.

Where fork is not the platform's safe default (macOS and Windows), the work simply runs in the
caller: a worker's serve function when the caller waits for it or stops it.
"""

import multiprocessing
import os
import signal
import sys
import traceback
import weakref
from collections.abc import Callable

_FORK_IS_SAFE = sys.platform.startswith("linux")
# Calls ``serve_calls_at_once`` runs side by side per usable core (see there).
_CALLS_PER_CORE = 2
# How often a waiting worker checks that its parent is still there (s).
_PARENT_POLL_S = 0.2
# The exit code of a worker that ended early, stopped or orphaned.
STOPPED_EXIT_CODE = 3

# Every live worker's sending end. A child closes its copies at once, so that a worker's pipe
# ends (EOF) when its caller dies, whatever was forked after it.
_SENDERS: weakref.WeakSet = weakref.WeakSet()
# Set in a worker by SIGTERM: its next wait for a message ends as if the caller were gone.
_stop_requested = False


def _request_stop(signum, frame) -> None:
    global _stop_requested
    _stop_requested = True


def _in_child(target: Callable, *args) -> None:
    """Runs ``target(*args)`` in a forked child, set up as the module docstring says."""
    for sender in list(_SENDERS):
        sender.close()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    # Not the handler a CLI parent may have set (it raises there).
    signal.signal(signal.SIGTERM, _request_stop)
    try:
        target(*args)
    except EOFError:  # its caller is gone or stopped it: nothing to report
        sys.exit(STOPPED_EXIT_CODE)


class _Child:
    """A forked child process; ``wait`` joins it and reports a failure."""

    def __init__(self, description: str, target: Callable, *args):
        self._description = description
        self._process = multiprocessing.get_context("fork").Process(
            target=_in_child, args=(target, *args), daemon=True
        )
        self._process.start()

    def wait(self) -> None:
        """Blocks until the child ends.

        Raises:
            RuntimeError: the child failed (its traceback went to stderr) or was killed.
        """
        self._process.join()
        if self._process.exitcode != 0:
            raise RuntimeError(
                f"{self._description} failed in its worker process "
                f"(exit code {self._process.exitcode}; its traceback is on stderr above)"
            )

    def join(self) -> None:
        """Blocks until the child ends, whatever its exit code."""
        self._process.join()


class _Stop:
    """What ``Worker.stop`` sends: the worker's ``recv`` raises EOFError on it."""


class _Replay:
    """What a serve function reads where no child runs: the objects sent, then the end."""

    def __init__(self, objects: list, stopped: bool):
        self._objects = iter(objects)
        self._stopped = stopped

    def recv(self):
        message = next(self._objects, None)
        if message is None and self._stopped:
            raise EOFError("the caller stopped")
        return message


class _FromParent:
    """A worker's end of its pipe: ``recv`` raises EOFError once the caller is gone or stops."""

    def __init__(self, connection, parent_pid: int):
        self._connection, self._parent_pid = connection, parent_pid

    def recv(self):
        # What was sent is read first: a stop request takes effect only when nothing is waiting.
        while not self._connection.poll(_PARENT_POLL_S):
            # A dead parent's child is adopted by another process (init or a subreaper).
            if _stop_requested or os.getppid() != self._parent_pid:
                raise EOFError("the caller is gone")
        try:
            message = self._connection.recv()
        except OSError:  # the caller died half-way through a message
            raise EOFError("the caller is gone") from None
        if isinstance(message, _Stop):
            raise EOFError("the caller stopped")
        return message


class Worker:
    """A forked child running ``serve(connection, *args)``, fed the objects ``send`` passes.

    The child reads them with ``connection.recv()``: None once the caller is done (``wait``), or
    EOFError if the caller stops it or is gone (see the module docstring).
    """

    def __init__(self, description: str, serve: Callable, *args):
        """Forks the child now; where fork is unsafe, ``wait`` serves what was sent in the caller.

        Args:
            description: what the worker does, as a failure's message names it.
            serve: the serve function, called as ``serve(connection, *args)``.
            *args: its further arguments.
        """
        self._serve, self._args = serve, args
        self._child = None
        self._unsent: list = []
        self._ended = False
        if _FORK_IS_SAFE:
            receiver, self._sender = multiprocessing.get_context("fork").Pipe(duplex=False)
            _SENDERS.add(self._sender)
            parent = _FromParent(receiver, os.getpid())
            self._child = _Child(description, serve, parent, *args)
            receiver.close()

    def send(self, message) -> None:
        """Passes ``message`` (picklable) to the child.

        If the child has died, nothing happens here: ``wait`` reports it.
        """
        if self._child is None:
            self._unsent.append(message)
            return
        try:
            self._sender.send(message)
        except OSError:  # the child is gone; its exit code says why
            pass

    def wait(self) -> None:
        """Tells the child nothing more is coming and blocks until it ends.

        Raises:
            RuntimeError: the child failed or was killed.
        """
        if self._end(None):
            self._child.wait()

    def stop(self) -> None:
        """Tells the child to end early (its ``recv`` raises EOFError) and blocks until it ends.

        For a caller that was interrupted; a worker already waited for or stopped is left alone.
        """
        if self._end(_Stop()):
            self._child.join()

    def _end(self, last_message) -> bool:
        """Sends the last message once; True if there is a child to wait for."""
        if self._ended:
            return False
        self._ended = True
        if self._child is None:
            try:
                self._serve(_Replay(self._unsent, stopped=last_message is not None), *self._args)
            except EOFError:  # stopped: as a child would, it just ends
                pass
            return False
        self.send(last_message)
        self._sender.close()
        return True


def serve_calls(connection, warm_up: Callable[[], None]) -> None:
    """A ``Worker`` serve function: ``warm_up()`` at once, then each call received, until None.

    The calls are ``(function, args, kwargs)``, made in the order received.
    """
    warm_up()
    while (call := connection.recv()) is not None:
        function, args, kwargs = call
        function(*args, **kwargs)


def serve_calls_at_once(connection, warm_up: Callable[[], None]) -> None:
    """``serve_calls`` for independent calls (plots): each runs at once, in a fork of the worker.

    A call is forked from the worker as it arrives, after ``warm_up`` (so every fork starts with
    what it imported and set up), with up to two running per core the process may use
    (``_CALLS_PER_CORE``): calls past the cores share them, so three plots on two cores end in
    about one and a half plots' time, where one call per core would leave a core idle while the
    third ran (two plots' time); the cap bounds the forks' memory. Where no child runs
    (``Worker`` without fork), the calls run one after the other, as ``serve_calls`` makes them.

    When the worker is stopped or finds its caller gone, the calls still running are killed. A
    call is short (a plot), so the worker waits for it without polling for its caller: one still
    running when the caller is killed ends with its call.

    Raises:
        RuntimeError: once every call has ended, naming each that failed (by function and first
            argument; its traceback is on stderr).
    """
    if isinstance(connection, _Replay):
        serve_calls(connection, warm_up)
        return
    warm_up()
    most_at_once = _CALLS_PER_CORE * usable_cores()
    running: dict[int, str] = {}
    failed: list[str] = []
    try:
        while (call := connection.recv()) is not None:
            if len(running) >= most_at_once:
                failed += _reap_one(running)
            function, args, kwargs = call
            pid = os.fork()
            if pid == 0:
                _run_forked_call(function, args, kwargs)
            running[pid] = f"{function.__name__}({args[0] if args else ''})"
    except EOFError:  # the caller stopped or is gone: its calls' work goes with it
        for pid in running:
            os.kill(pid, signal.SIGKILL)
        raise
    finally:  # every fork is reaped, however the loop ended
        while running:
            failed += _reap_one(running)
    if failed:
        raise RuntimeError(f"{', '.join(failed)} failed (tracebacks on stderr above)")


def usable_cores() -> int:
    """How many cores this process may run on (its affinity, not the machine's count)."""
    return len(os.sched_getaffinity(0))


def _run_forked_call(function: Callable, args: tuple, kwargs: dict) -> None:
    """In a fork: makes the call, then ends the fork (0, or 1 with the traceback on stderr)."""
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    code = 0
    try:
        function(*args, **kwargs)
    except BaseException:
        traceback.print_exc()
        code = 1
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        # Not sys.exit: a fork must not run its parent's clean-up (multiprocessing's, atexit's).
        os._exit(code)


def _reap_one(running: dict[int, str]) -> list[str]:
    """Waits for a child to end: [its name] if it is one of the ``running`` forks and failed.

    Any other child of the worker (one its warm-up started and left, say) is reaped and passed
    over, and the wait goes on.
    """
    while True:
        pid, status = os.wait()
        if pid in running:
            name = running.pop(pid)
            return [] if os.waitstatus_to_exitcode(status) == 0 else [name]
