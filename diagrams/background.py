"""Run one function in a forked child process while the caller goes on, to use a second core.

`maskless simulate` renders its plot this way while it writes the recording. Forking shares the
finished run with the child without copying or pickling it. Where fork is not the platform's safe
default (macOS and Windows), the function simply runs in the caller, at once.
"""

import multiprocessing
import sys
from collections.abc import Callable


class BackgroundTask:
    """A function running in a forked child; ``wait`` joins it and reports a failure."""

    def __init__(self, description: str, function: Callable, *args):
        self._description = description
        self._process = None
        if sys.platform.startswith("linux"):
            self._process = multiprocessing.get_context("fork").Process(
                target=function, args=args, daemon=True
            )
            self._process.start()
        else:
            function(*args)

    def wait(self) -> None:
        """Blocks until the task ends.

        Raises:
            RuntimeError: the child failed (its traceback went to stderr) or was killed.
        """
        if self._process is None:
            return
        self._process.join()
        if self._process.exitcode != 0:
            raise RuntimeError(
                f"{self._description} failed in its worker process "
                f"(exit code {self._process.exitcode}; its traceback is on stderr above)"
            )
