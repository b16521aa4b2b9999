"""The batched simulator: half of each batch in a worker thread."""

from __future__ import annotations

import os
from collections import Counter
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from grader.datasets import load
from grader.gap import backend, baseline
from grader.gap.backend import Backend, Point, _halves, stretches, worker
from grader.gap.runs import prepare_runs
from grader.model import engine
from grader.model.effects import EffectSet

from .conftest import MakeDataset


def _requests(make: MakeDataset) -> tuple[list, list[tuple[Point, int]]]:
    ds = load(make("quiet"))
    runs = prepare_runs(ds, ds.given["sample_time"])[1]
    base = baseline.choose(ds, runs, key=None, implied_kfb=None).params
    points = [Point(base.with_(Kce=base.Kce * f), EffectSet.from_quantities({"coulomb_friction": {"Fc": fc}}))
              for f, fc in ((1.0, "0.5 lbf"), (1.3, "2 lbf"), (0.8, "0.1 lbf"))]
    return runs, [(pt, i) for pt in points for i in range(len(runs))]


def test_a_worker_thread_returns_what_this_thread_computes(make: MakeDataset) -> None:
    """Half of each batch in a worker thread: every position equals the one simulated here alone, in order,
    batch after batch (on any number of cores)."""
    runs, requests = _requests(make)
    alone = Backend(runs)(requests)
    with ThreadPoolExecutor(max_workers=1) as pool:
        both = Backend(runs, executor=pool)
        first, second = both(requests), both(requests[::-1])
    assert len(first) == len(alone) == len(second)
    for a, b, c in zip(alone, first, second[::-1]):
        assert a.shape == b.shape and np.array_equal(a, b) and np.array_equal(a, c)


def test_a_batch_whose_runs_all_fall_to_one_thread_is_still_simulated(make: MakeDataset) -> None:
    """A fold's last round asks one point for runs 0 and 2 only: every other request of each run puts both here
    and none in the worker, which once got an empty batch and raised."""
    runs, requests = _requests(make)
    pt = requests[0][0]
    with ThreadPoolExecutor(max_workers=1) as pool:
        both = Backend(runs, executor=pool)
        for which in ((0, 2), (1, 3), (1,), (0, 2, 4)):
            batch = [(pt, i) for i in which]
            assert all(np.array_equal(a, b) for a, b in zip(both(batch), Backend(runs)(batch), strict=True))


def test_the_worker_is_a_thread_where_a_second_core_exists_and_the_engine_lets_it_run() -> None:
    """The diagnosis gets its worker thread on two cores or more and none when disabled; the engine's batch loop
    releases the GIL, without which the thread would wait for this one."""
    with worker() as w:
        assert (w is None) == ((os.cpu_count() or 1) < 2)
        assert w is None or isinstance(w, ThreadPoolExecutor)
    with worker(enabled=False) as w:
        assert w is None
    assert engine._run_batch.targetoptions.get("nogil") is True


@pytest.mark.parametrize("runs, points", [(6, 80), (6, 1), (5, 7), (1, 9), (2, 3)])
def test_each_runs_requests_are_shared_by_both_threads(runs: int, points: int) -> None:
    """A fit's batch asks every point for every run in order; every other request of the list gave the worker all
    of the odd runs' (a stick-slip step run cost ten times the others on run A's 0197: 449 ms there, 105 here).
    Now each run's requests are split within one, and half the batch goes each way."""
    requests = [(None, i) for _ in range(points) for i in range(runs)]
    away = _halves(requests)  # type: ignore[arg-type]
    there = Counter(i for (_, i), a in zip(requests, away) if a)
    here = Counter(i for (_, i), a in zip(requests, away) if not a)
    assert all(abs(there[i] - here[i]) <= 1 for i in range(runs))
    assert abs(sum(away) - (len(away) - sum(away))) <= runs


def test_engine_calls_stay_within_their_budget_and_change_no_bit(make: MakeDataset, monkeypatch: pytest.MonkeyPatch
                                                                  ) -> None:
    """A large batch goes to the engine in calls of at most MAX_CALL_SAMPLES padded samples (five 30 s runs asked
    for 700 at once per thread, and the diagnosis peaked at 2.4 GB); the positions are those of one call, in order.
    A lab-sized batch stays one call."""
    runs, requests = _requests(make)
    sizes: list[tuple[int, int]] = []
    real = backend.position_batch

    def spy(params, controllers, effects, commands, noise=None, **kw):  # noqa: ANN001, ANN003, ANN202
        sizes.append((len(commands), max(c.size for c in commands)))
        return real(params, controllers, effects, commands, noise, **kw)

    monkeypatch.setattr(backend, "position_batch", spy)
    whole = Backend(runs)(requests)
    assert sizes == [(len(requests), max(r.n for r in runs))]
    sizes.clear()
    budget = 3 * max(r.n for r in runs)
    monkeypatch.setattr(backend, "MAX_CALL_SAMPLES", budget)
    parts = Backend(runs)(requests)
    assert len(sizes) > 2 and sum(n for n, _ in sizes) == len(requests)
    assert all(n * k <= budget for n, k in sizes)
    assert all(np.array_equal(a, b) for a, b in zip(parts, whole, strict=True))


@given(st.lists(st.integers(1, 50), max_size=40), st.integers(1, 120))
def test_engine_calls_cover_every_request_once_in_order(lengths: list[int], budget: int) -> None:
    """Consecutive stretches, every request in exactly one; each within the budget once padded to its longest
    run, unless a single run is longer, and as long as it can be: the next request would take it over."""
    calls = stretches(lengths, budget, padded=True)
    assert [k for s in calls for k in range(len(lengths))[s]] == list(range(len(lengths)))
    for s in calls:
        part = lengths[s]
        assert part and (len(part) * max(part) <= budget or len(part) == 1)
        if s.stop < len(lengths):
            assert (len(part) + 1) * max(*part, lengths[s.stop]) > budget
