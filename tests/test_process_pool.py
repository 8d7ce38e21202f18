"""diagrams/process_pool.py: results as they finish, and a process per item when asked."""

import concurrent.futures
import os

from maskless.diagrams.process_pool import bounded, pool_results


def _worker_pid(_item) -> int:
    return os.getpid()


def _square(item: int) -> int:
    return item * item


def test_every_item_comes_back_once_whatever_order_they_finish_in():
    assert sorted(pool_results(_square, range(7), workers=2)) == [n * n for n in range(7)]


def test_a_fresh_worker_per_item_runs_each_item_in_a_process_of_its_own():
    shared = list(pool_results(_worker_pid, range(4), workers=1))
    fresh = list(pool_results(_worker_pid, range(4), workers=1, fresh_worker_per_item=True))
    # One worker, reused: every item saw the same process; fresh: four different ones.
    assert len(set(shared)) == 1
    assert len(set(fresh)) == 4
    assert os.getpid() not in fresh


def test_no_more_than_the_window_is_submitted_before_a_result_is_collected():
    submitted, in_flight_most = [], 0

    def submit(item):
        submitted.append(item)
        future = concurrent.futures.Future()
        future.set_result(item)
        return future

    def first_done(pending):
        nonlocal in_flight_most
        in_flight_most = max(in_flight_most, len(pending))
        oldest = min(pending, key=lambda future: future.result())
        return {oldest}, pending - {oldest}

    assert list(bounded(submit, first_done, range(10), window=3)) == list(range(10))
    assert in_flight_most == 3
    assert submitted == list(range(10))
