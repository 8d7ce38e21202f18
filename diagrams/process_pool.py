"""Results of many independent jobs as they finish, from a spawned process pool.

The Monte Carlo sweep and the fault matrix both run one pure function over many items. Workers are
spawned, not forked (a fork would copy the caller's Drake and threads mid-state), and end when the
caller is gone, even killed by SIGKILL (each watches its parent). At most a few jobs per worker
are submitted and not yet collected, so memory stays flat however many there are.
"""

import concurrent.futures
import itertools
import multiprocessing
import os
import threading
import time
from collections.abc import Callable, Iterable, Iterator

# Jobs submitted per worker ahead of the results collected: enough to keep every worker busy.
IN_FLIGHT_PER_WORKER = 4


def pool_results(
    function: Callable, items: Iterable, workers: int, fresh_worker_per_item: bool = False
) -> Iterator:
    """``function(item)`` for each item, in the order they finish, on ``workers`` processes.

    With ``fresh_worker_per_item`` each item runs in a process of its own, so its result cannot
    depend on what the worker ran before it (allocator state, caches), only on the item.
    """
    context = multiprocessing.get_context("spawn")
    with concurrent.futures.ProcessPoolExecutor(
        workers,
        mp_context=context,
        initializer=exit_with_parent,
        initargs=(os.getpid(),),
        max_tasks_per_child=1 if fresh_worker_per_item else None,
    ) as pool:

        def first_done(pending):
            return concurrent.futures.wait(pending, return_when=concurrent.futures.FIRST_COMPLETED)

        yield from bounded(
            lambda item: pool.submit(function, item),
            first_done,
            items,
            workers * IN_FLIGHT_PER_WORKER,
        )


def bounded(
    submit: Callable[[object], object],
    first_done: Callable[[set], tuple[set, set]],
    items: Iterable,
    window: int,
) -> Iterator:
    """Results as they finish, with at most ``window`` items submitted and not yet collected."""
    queue = iter(items)
    pending = {submit(item) for item in itertools.islice(queue, window)}
    while pending:
        done, pending = first_done(pending)
        for future in done:
            yield future.result()
            for item in queue:
                pending.add(submit(item))
                break


def exit_with_parent(parent_pid: int) -> None:
    """A pool worker ends when the process that started it is gone (killed), not lingering."""

    def watch():
        while os.getppid() == parent_pid:
            time.sleep(0.5)
        os._exit(1)

    threading.Thread(target=watch, daemon=True).start()
