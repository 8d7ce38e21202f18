"""Work in forked child processes while the caller goes on, to use a second core.

- ``BackgroundTask`` forks once the work's inputs exist, so the child shares them without copying
  or pickling (`maskless identify` renders its plots this way).
- ``Worker`` forks early and serves what the caller sends it later (picklable objects, through a
  pipe): `maskless simulate` streams the recording to one while the loop runs, and has another
  import matplotlib meanwhile (~0.35 s) and then plot. Child processes, not threads: a thread's
  work would hold the GIL the simulation needs.

Where fork is not the platform's safe default (macOS and Windows), the work simply runs in the
caller: a task at once, a worker's serve function when the caller waits for it.
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
        """Forks the child running ``function(*args)``, or runs it here where fork is unsafe.

        Args:
            description: what the task does, as a failure's message names it.
            function: the work.
            *args: its arguments.
        """
        self._child = _Child(description, function, *args) if _FORK_IS_SAFE else None
        if self._child is None:
            function(*args)

    def wait(self) -> None:
        """Blocks until the task ends; raises RuntimeError if it failed."""
        if self._child is not None:
            self._child.wait()


class _Replay:
    """What a serve function reads where no child runs: the objects sent, then None."""

    def __init__(self, objects: list):
        self._objects = iter([*objects, None])

    def recv(self):
        return next(self._objects)


class Worker:
    """A forked child running ``serve(connection, *args)``, fed the objects ``send`` passes.

    The child reads them with ``connection.recv()``, then None once the caller is done. (An end
    marker, not the pipe's end: a child forked later holds a copy of the pipe, so closing it ends
    nothing.)
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
        if _FORK_IS_SAFE:
            receiver, self._sender = multiprocessing.get_context("fork").Pipe(duplex=False)
            self._child = _Child(description, serve, receiver, *args)
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
        if self._child is None:
            self._serve(_Replay(self._unsent), *self._args)
            return
        self.send(None)
        self._sender.close()
        self._child.wait()


def serve_calls(connection, warm_up: Callable[[], None]) -> None:
    """A ``Worker`` serve function: ``warm_up()`` at once, then each call received, until None.

    The calls are ``(function, args, kwargs)``, made in the order received.
    """
    warm_up()
    while (call := connection.recv()) is not None:
        function, args, kwargs = call
        function(*args, **kwargs)
