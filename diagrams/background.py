"""Run one function in a forked child process while the caller goes on, to use a second core.

Two ways to hand the child its work:

- ``BackgroundTask`` forks once the work's inputs exist, so the child shares them without copying
  or pickling (`maskless identify` renders its plots this way).
- ``WarmWorker`` forks early, lets the child do its slow preparation (importing matplotlib takes
  ~0.35 s) while the caller computes, then sends the function and its (picklable) arguments. A
  child process, not a thread: a thread's imports would hold the GIL the simulation needs.
  `maskless simulate` renders its plot this way while it writes the recording.

Where fork is not the platform's safe default (macOS and Windows), the work simply runs in the
caller, at once.
"""

import multiprocessing
import sys
from collections.abc import Callable

_FORK_IS_SAFE = sys.platform.startswith("linux")


class _Child:
    """A forked child process; ``wait`` joins it and reports a failure."""

    def __init__(self, description: str, target: Callable, *args):
        self._description = description
        self._process = multiprocessing.get_context("fork").Process(
            target=target, args=args, daemon=True
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


class BackgroundTask:
    """``function(*args)`` running in a forked child from now on."""

    def __init__(self, description: str, function: Callable, *args):
        self._child = _Child(description, function, *args) if _FORK_IS_SAFE else None
        if self._child is None:
            function(*args)

    def wait(self) -> None:
        """Blocks until the task ends; raises RuntimeError if it failed."""
        if self._child is not None:
            self._child.wait()


def _serve(connection, warm_up: Callable[[], None]) -> None:
    warm_up()
    try:
        function, args, kwargs = connection.recv()
    except EOFError:  # the caller gave up before sending any work
        return
    function(*args, **kwargs)


class WarmWorker:
    """A forked child that runs ``warm_up()`` now and one ``submit``-ted function later."""

    def __init__(self, description: str, warm_up: Callable[[], None]):
        self._child = None
        if _FORK_IS_SAFE:
            receiver, self._sender = multiprocessing.get_context("fork").Pipe(duplex=False)
            self._child = _Child(description, _serve, receiver, warm_up)
            receiver.close()

    def submit(self, function: Callable, *args, **kwargs) -> None:
        """Has the child run ``function(*args, **kwargs)`` (in the caller where fork is unsafe).
        The function and arguments must pickle."""
        if self._child is None:
            function(*args, **kwargs)
            return
        try:
            self._sender.send((function, args, kwargs))
        except OSError:  # the child died while warming up; ``wait`` reports how
            pass
        finally:
            self._sender.close()

    def wait(self) -> None:
        """Blocks until the submitted work ends; raises RuntimeError if it failed."""
        if self._child is not None:
            self._child.wait()
