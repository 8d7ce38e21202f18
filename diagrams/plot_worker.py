"""A worker process that imports matplotlib at once and draws the plots it is sent later.

A command starts it before its own heavy work (the loop, the estimators' imports), so the import
(about half a second) runs on the second core meanwhile and only the drawing is left at the end.
"""

from pathlib import Path

from maskless.diagrams.background import Worker, serve_calls


def prepare_plotting() -> None:
    """Imports what rendering needs, so the worker does it ahead of time."""
    import matplotlib.backends.backend_agg  # noqa: F401
    from matplotlib.figure import Figure  # noqa: F401


def start_plot_worker(destination: str | Path) -> Worker:
    """The worker: send it ``(function, args, kwargs)`` calls, then ``wait`` (or ``stop``).

    Args:
        destination: the file or folder it plots into, as a failure's message names it.
    """
    return Worker(f"plotting into {destination}", serve_calls, prepare_plotting)
