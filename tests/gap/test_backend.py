"""The batched simulator: half of each batch in a worker thread."""

from __future__ import annotations

import numpy as np
import pytest

from grader.datasets import load
from grader.gap import baseline
from grader.gap.backend import Backend, Point, worker
from grader.gap.runs import prepare_runs
from grader.model.effects import EffectSet

from .conftest import MakeDataset


def _requests(make: MakeDataset) -> tuple[list, list[tuple[Point, int]]]:
    ds = load(make("quiet"))
    runs = prepare_runs(ds, ds.given["sample_time"])
    base = baseline.choose(ds, runs, key=None, implied_kfb=None).params
    points = [Point(base.with_(Kce=base.Kce * f), EffectSet.from_quantities({"coulomb_friction": {"Fc": fc}}))
              for f, fc in ((1.0, "0.5 lbf"), (1.3, "2 lbf"), (0.8, "0.1 lbf"))]
    return runs, [(pt, i) for pt in points for i in range(len(runs))]


def test_the_worker_thread_returns_what_this_thread_computes(make: MakeDataset) -> None:
    """Half of each batch in the worker thread: every position equals the one simulated here alone, in order,
    batch after batch."""
    runs, requests = _requests(make)
    alone = Backend(runs)(requests)
    with worker() as w:
        if w is None:
            pytest.skip("a single core")
        both = Backend(runs, executor=w)
        first, second = both(requests), both(requests[::-1])
    assert len(first) == len(alone) == len(second)
    for a, b, c in zip(alone, first, second[::-1]):
        assert a.shape == b.shape and np.array_equal(a, b) and np.array_equal(a, c)
