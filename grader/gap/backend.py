"""Batched simulation of model points on the dataset's runs.

A :class:`Point` is one model (linear parameters plus an :class:`EffectSet`). A request
``(point, run index)`` asks for that model's position x_k [in] on that run, with the
model's controller reading x_k plus the run's estimated reading noise. All requests go
through the compiled rig engine (:func:`grader.model.rig.simulate_positions`), whatever their
number (half of them in a forked worker process when :func:`worker` provides one: the
diagnosis uses two cores; the worker hands its positions back through memory shared with this
process, not through a pipe). Known hardware limits (DAC ±10 V, amplifier ±i_max) are part of
every model, as they are of the rig.
"""

from __future__ import annotations

import mmap
import multiprocessing as mp
import os
from collections.abc import Iterator, Sequence
from concurrent.futures import Executor, ProcessPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from grader.gap.runs import GapRun
from grader.model.effects import EffectSet
from grader.model.params import Controller, RigParams
from grader.model.rig import position_batch

Array = NDArray[np.float64]
#: A trial model needing more RK4 substeps per sample than this is not simulated (NaN, a capped residual):
#: every rig of the realistic space needs under ten, and a fit that strays to a stiffer β/Vt or Kce would
#: otherwise cost minutes per request.
FIT_MAX_SUBSTEPS = 100
#: Bytes of the anonymous shared memory the worker returns positions through (only the pages a batch touches
#: are used); a batch whose positions need more comes back pickled. A fit's largest batch needs a few MB.
SHARED_BYTES = 1 << 26


@dataclass(frozen=True)
class Point:
    """One model: linear parameters and unmodelled effects."""

    params: RigParams
    effects: EffectSet = field(default_factory=EffectSet)


@dataclass(frozen=True)
class Worker:
    """A forked worker process and the memory it shares with this one (both see the same pages)."""

    pool: Executor
    shared: mmap.mmap


_SHARED: mmap.mmap | None = None  # in the worker: Worker.shared


def _attach(shared: mmap.mmap) -> None:
    global _SHARED
    _SHARED = shared


@contextmanager
def worker(enabled: bool = True) -> Iterator[Worker | None]:
    """One forked worker process for half of each batch, where fork and a second core exist."""
    if not enabled or "fork" not in mp.get_all_start_methods() or (os.cpu_count() or 1) < 2:
        yield None
        return
    with mmap.mmap(-1, SHARED_BYTES) as shared, ProcessPoolExecutor(
            max_workers=1, mp_context=mp.get_context("fork"), initializer=_attach, initargs=(shared,)) as ex:
        yield Worker(ex, shared)


def _positions(points: Sequence[Point], which: Sequence[int], runs: Sequence[tuple[Controller, Array, Array]]
               ) -> list[Array]:
    """x_k [in] of each point on run ``which[j]``; ``runs`` holds each run's (controller, command, noise)."""
    return position_batch([pt.params for pt in points], [runs[i][0] for i in which], [pt.effects for pt in points],
                          [runs[i][1] for i in which], [runs[i][2] for i in which],
                          max_substeps=FIT_MAX_SUBSTEPS).run()


def _positions_shared(points: Sequence[Point], which: Sequence[int], runs: Sequence[tuple[Controller, Array, Array]]
                      ) -> list[Array] | None:
    """In the worker: :func:`_positions`, written one after another into the shared memory (None), or returned
    where they do not fit."""
    out = _positions(points, which, runs)
    n = sum(x.size for x in out)
    if _SHARED is None or 8 * n > len(_SHARED):
        return out
    np.concatenate(out, out=np.frombuffer(_SHARED, dtype=np.float64, count=n))
    return None


class Backend:
    """Simulates requests (see module docstring)."""

    def __init__(self, runs: Sequence[GapRun], *, executor: Worker | None = None) -> None:
        self.runs = list(runs)
        self.executor = executor
        self._inputs = [(r.controller, r.r, r.noise) for r in self.runs]

    def __call__(self, requests: Sequence[tuple[Point, int]]) -> list[Array]:
        """x_k [in] for each request, in order. With an executor, every other request is simulated
        there: only the points and run numbers travel (the worker builds its own batch)."""
        if self.executor is None or len(requests) < 2:
            return self._here(requests)
        there = requests[1::2]
        pending = self.executor.pool.submit(_positions_shared, [pt for pt, _ in there], [i for _, i in there],
                                            self._inputs)
        here = self._here(requests[::2])
        out: list[Array] = [np.empty(0)] * len(requests)
        out[::2], out[1::2] = here, pending.result() or self._shared(there)
        return out

    def _shared(self, requests: Sequence[tuple[Point, int]]) -> list[Array]:
        """The worker's positions for ``requests`` from the shared memory (copied: the next batch overwrites it);
        each is as long as its run's command."""
        assert self.executor is not None
        sizes = [self._inputs[i][1].size for _, i in requests]
        flat = np.frombuffer(self.executor.shared, dtype=np.float64, count=sum(sizes)).copy()
        return np.split(flat, np.cumsum(sizes)[:-1])

    def _here(self, requests: Sequence[tuple[Point, int]]) -> list[Array]:
        return _positions([pt for pt, _ in requests], [i for _, i in requests], self._inputs)

    def all_runs(self, points: Sequence[Point]) -> list[list[Array]]:
        """x for every point on every run: ``result[p][i]``."""
        n = len(self.runs)
        flat = self([(pt, i) for pt in points for i in range(n)])
        return [flat[k * n:(k + 1) * n] for k in range(len(points))]
