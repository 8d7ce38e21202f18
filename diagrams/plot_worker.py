"""A worker process that imports matplotlib at once and draws the plots it is sent later.

A command starts it before its own heavy work (the loop, the estimators' imports), so the import
(about half a second) runs on the second core meanwhile and only the drawing is left at the end.
The plots it is sent are drawn at once, each in its own fork of the warmed-up worker
(``serve_calls_at_once``): `maskless identify`'s three take about one and a half plots' time on
two cores.
"""

from pathlib import Path

from maskless.diagrams.background import Worker, serve_calls_at_once


def prepare_plotting() -> None:
    """Imports what rendering needs and draws one small figure with text, to a buffer.

    The first figure a process draws pays for setting up fonts and text layout (about 0.05 s);
    drawn here, while the worker waits for its calls, every fork starts with that done.
    """
    import io

    import matplotlib.backends.backend_agg  # noqa: F401

    # Long signals are drawn from its samples (``fit_plots.drawn_samples``): imported once here,
    # not in every fork.
    import tsdownsample  # noqa: F401
    from matplotlib.figure import Figure

    figure = Figure(figsize=(2, 1.5))
    axis = figure.subplots()
    axis.plot([0, 1], [0, 1], label="warm")
    axis.set_title("warm")
    axis.set_xlabel("x")
    axis.legend(fontsize=8)
    figure.savefig(io.BytesIO(), format="png", dpi=100)


def start_plot_worker(destination: str | Path) -> Worker:
    """The worker: send it ``(function, args, kwargs)`` calls, then ``wait`` (or ``stop``).

    Args:
        destination: the file or folder it plots into, as a failure's message names it.
    """
    return Worker(f"plotting into {destination}", serve_calls_at_once, prepare_plotting)
