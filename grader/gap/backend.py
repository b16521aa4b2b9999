"""Batched simulation of model points on the dataset's runs.

A :class:`Point` is one model (linear parameters plus an :class:`EffectSet`). A request
``(point, run index)`` asks for that model's position x_k [in] on that run, with the
model's controller reading x_k plus the run's estimated reading noise; a replaying backend drives each run by the
controller output the rig recorded instead (:mod:`grader.gap.replay`). All requests go
through the compiled rig engine (:func:`grader.model.rig.simulate_positions`), whatever their
number (half of each run's in a worker thread when :func:`worker` provides one: the compiled engine
releases the GIL, so the diagnosis uses two cores). Known hardware limits (DAC ±10 V,
amplifier ±i_max) are part of every model, as they are of the rig.
"""

from __future__ import annotations

import os
from collections import Counter
from collections.abc import Iterator, Sequence
from concurrent.futures import Executor, ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from grader.gap.runs import GapRun, null_shift
from grader.model.effects import EffectSet
from grader.model.params import Controller, RigParams
from grader.model.rig import position_batch

Array = NDArray[np.float64]
#: A trial model needing more RK4 substeps per sample than this is not simulated (NaN, a capped residual):
#: every rig of the realistic space needs under ten, and a fit that strays to a stiffer β/Vt or Kce would
#: otherwise cost minutes per request.
FIT_MAX_SUBSTEPS = 100
#: Most samples (runs × the longest among them) one engine call simulates: its five row arrays then hold
#: 16 MB each. A fit on five 30 s runs asks for 700 runs at once per thread: in one call each, the diagnosis
#: peaked at 2.4 GB. Run A's lab-sized datasets need at most 1.1 million per call on two cores.
MAX_CALL_SAMPLES = 2_000_000


@dataclass(frozen=True)
class Point:
    """One model: linear parameters, unmodelled effects, and a fitted valve null as the shift [V] of the controller
    output the valve sees (beyond the null held in the runs, :attr:`GapRun.null_u`)."""

    params: RigParams
    effects: EffectSet = field(default_factory=EffectSet)
    null_u: float = 0.0


def _with_null(point: Point, run: tuple[Controller, Array, Array], replay: bool) -> tuple[Array, Array]:
    """The run's (command [in], noise [in] or, replayed, recorded controller output [V]) with ``point``'s null in
    them: a replayed output shifted by null_u, else the command by :func:`~grader.gap.runs.null_shift`."""
    c, r, other = run
    if not point.null_u:
        return r, other
    if replay:
        return r, other + point.null_u
    return r + null_shift(c, point.null_u / point.params.k_fb), other


@contextmanager
def worker(enabled: bool = True) -> Iterator[Executor | None]:
    """One worker thread for half of each batch, where a second core exists. It shares this process's memory:
    no fork, nothing pickled, no positions sent back through a pipe."""
    if not enabled or (os.cpu_count() or 1) < 2:
        yield None
        return
    with ThreadPoolExecutor(max_workers=1, thread_name_prefix="grader-sim") as ex:
        yield ex


def stretches(sizes: Sequence[int], budget: int, *, padded: bool) -> list[slice]:
    """Consecutive stretches of items of these sizes [samples], each as long as stays within ``budget`` (one item
    at least): their sum, or with ``padded`` their number times the largest (rows of an engine call)."""
    out, start, total, largest = [], 0, 0, 0
    for k, n in enumerate(sizes):
        cost = (k - start + 1) * max(largest, n) if padded else total + n
        if k > start and cost > budget:
            out.append(slice(start, k))
            start, total, largest = k, 0, 0
        total, largest = total + n, max(largest, n)
    return [*out, slice(start, len(sizes))] if len(sizes) else out


def _positions(points: Sequence[Point], which: Sequence[int], runs: Sequence[tuple[Controller, Array, Array]],
               replay: bool = False) -> list[Array]:
    """x_k [in] of each point on run ``which[j]``; ``runs`` holds each run's (controller, command, noise), or with
    ``replay`` (controller, command, recorded controller output [V]).
    Simulated in engine calls of at most :data:`MAX_CALL_SAMPLES` (each run's result is its own: how they
    are grouped changes no bit)."""
    out: list[Array] = []
    for part in stretches([runs[i][1].size for i in which], MAX_CALL_SAMPLES, padded=True):
        pts, idx = points[part], which[part]
        ins = [_with_null(pt, runs[i], replay) for pt, i in zip(pts, idx)]
        out += position_batch([pt.params for pt in pts], [runs[i][0] for i in idx], [pt.effects for pt in pts],
                              [r for r, _ in ins], [x for _, x in ins], max_substeps=FIT_MAX_SUBSTEPS,
                              replay=replay).run()
    return out


def _halves(requests: Sequence[tuple[Point, int]]) -> list[bool]:
    """Which requests the worker takes: every other request of each run, starting with the first of the odd runs
    and the second of the even ones. A run can cost ten times another (a stick-slip step's events), so each run is
    shared; every other request of the whole list gave all of one run's requests to one thread on a fit's batches
    (each point asks for every run, in order)."""
    seen: Counter[int] = Counter()
    away = []
    for _, i in requests:
        away.append((seen[i] + i) % 2 == 1)
        seen[i] += 1
    return away


class Backend:
    """Simulates requests (see module docstring)."""

    def __init__(self, runs: Sequence[GapRun], *, executor: Executor | None = None, replay: bool = False) -> None:
        """``replay``: each run is driven by its recorded controller output (every run must have one)."""
        self.runs = list(runs)
        self.executor, self.replay = executor, replay
        self._inputs = [(r.controller, r.r, r.u + r.null_u) if replay else (r.controller, r.r + r.command_shift, r.noise)
                        for r in self.runs]  # the valve's null in the model's inputs (grader.gap.null)

    def __call__(self, requests: Sequence[tuple[Point, int]]) -> list[Array]:
        """x_k [in] for each request, in order. With an executor, half the requests (:func:`_halves`) are
        simulated there, as a batch of their own, while this thread simulates the rest."""
        if self.executor is None or len(requests) < 2:
            return self._here(requests)
        away = _halves(requests)
        if all(away) or not any(away):  # each run asked once, all odd or all even: halve the list instead
            away = [k % 2 == 1 for k in range(len(requests))]
        there = [q for q, a in zip(requests, away) if a]
        pending = self.executor.submit(_positions, [pt for pt, _ in there], [i for _, i in there], self._inputs,
                                       self.replay)
        here = iter(self._here([q for q, a in zip(requests, away) if not a]))
        done = iter(pending.result())
        return [next(done) if a else next(here) for a in away]

    def _here(self, requests: Sequence[tuple[Point, int]]) -> list[Array]:
        return _positions([pt for pt, _ in requests], [i for _, i in requests], self._inputs, self.replay)

    def all_runs(self, points: Sequence[Point]) -> list[list[Array]]:
        """x for every point on every run: ``result[p][i]``."""
        n = len(self.runs)
        flat = self([(pt, i) for pt in points for i in range(n)])
        return [flat[k * n:(k + 1) * n] for k in range(len(points))]
