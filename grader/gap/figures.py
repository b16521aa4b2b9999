"""The report's figures as plain data, and the helper processes that draw them.

A figure job is a :class:`RunFigure` or a :class:`CandidatesFigure`: arrays, numbers and the
words to print, nothing else. Drawing one needs numpy and matplotlib only (:mod:`grader.gap.plots`),
so helpers forked before the diagnosis imports anything heavy spend the time it takes the
diagnosis to import scipy importing matplotlib on the other core, at a lower priority
(:data:`NICE`), and then wait. This module imports nothing but the standard library and numpy's
typing at load.
"""

from __future__ import annotations

import gc
import importlib
import multiprocessing as mp
import os
from collections.abc import Iterator, Sequence
from concurrent.futures import BrokenExecutor, ProcessPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Union

#: Most helpers started; one per core (this process only waits for them while they draw).
MAX_HELPERS = 3
#: Niceness the helpers add to their own: their import of matplotlib yields the cores to the diagnosis, which
#: needs them first, and they draw when it waits.
NICE = 10


@dataclass(frozen=True)
class RunFigure:
    """One run's figure: time [s], command, measured, linear and augmented model [in]; the title, the
    augmented model's legend entry, the step time [s] and the shaded segments (name, t0 [s], t1 [s])."""

    t: Any
    r: Any
    y: Any
    y_linear: Any
    y_augmented: Any
    title: str
    augmented_label: str
    start: float
    bands: tuple[tuple[str, float, float], ...]


@dataclass(frozen=True)
class CandidatesFigure:
    """Candidates' names, held-out shrink and held-out NRMSE (fractions), whether each is the verdict, and
    the verdict's name."""

    names: tuple[str, ...]
    shrink: tuple[float, ...]
    heldout: tuple[float, ...]
    is_verdict: tuple[bool, ...]
    verdict: str


Job = Union[RunFigure, CandidatesFigure]


def draw(job: Job) -> bytes:
    """One figure's PNG bytes (matplotlib is imported here, where the figures are drawn)."""
    plots = importlib.import_module("grader.gap.plots")
    return plots.run_figure(job) if isinstance(job, RunFigure) else plots.candidates_figure(job)


@dataclass(frozen=True)
class PlotHelpers:
    """Forked helper processes and the index of the next figure to draw, shared with them."""

    pool: ProcessPoolExecutor
    size: int
    next_figure: Any  # multiprocessing.Value("i")


_NEXT: Any = None  # in a helper: its PlotHelpers.next_figure


def _warm(next_figure: Any) -> None:
    global _NEXT
    _NEXT = next_figure
    if hasattr(os, "nice"):
        os.nice(NICE)  # the diagnosis, importing scipy meanwhile, comes first; the figures come after it
    importlib.import_module("grader.gap.plots").warm()  # matplotlib imported and fonts loaded while the parent works
    gc.freeze()  # what is imported stays: later collections skip it
    gc.enable()  # figures leave cyclic garbage (the parent may have paused the collector)


def _claim(next_figure: Any) -> int:
    with next_figure.get_lock():
        k = int(next_figure.value)
        next_figure.value = k + 1
    return k


def _drain(jobs: Sequence[Job], next_figure: Any = None) -> dict[int, bytes]:
    """Draw figures in the order claimed, until none is left: {index: PNG}."""
    counter = _NEXT if next_figure is None else next_figure
    out = {}
    while (k := _claim(counter)) < len(jobs):
        out[k] = draw(jobs[k])
    return out


@contextmanager
def plot_helpers() -> Iterator[PlotHelpers | None]:
    """Helper processes for the figures, forked now (one per core, at most :data:`MAX_HELPERS`), each
    importing matplotlib at once. Open them before importing the diagnosis: they use the cores it leaves
    idle, and are ready when it ends. None where fork or a second core is missing."""
    cpus = os.cpu_count() or 1
    if cpus < 2 or "fork" not in mp.get_all_start_methods():
        yield None
        return
    ctx = mp.get_context("fork")
    size, next_figure = min(cpus, MAX_HELPERS), ctx.Value("i", 0)
    with ProcessPoolExecutor(size, mp_context=ctx, initializer=_warm, initargs=(next_figure,)) as pool:
        for _ in range(size):
            pool.submit(int)  # start every helper now
        yield PlotHelpers(pool, size, next_figure)


def draw_all(jobs: Sequence[Job], helpers: PlotHelpers | None) -> list[bytes]:
    """Every figure's PNG, in order. With ``helpers``, they draw while this process waits (it has not
    imported matplotlib; importing it would cost more than the figures), the candidates' figure (the slowest:
    laid out twice) first; a figure a dead helper held, or any figure when none is left, is drawn here. The
    bytes do not depend on who draws which, nor in what order (a helper draws its runs on one reused canvas)."""
    if helpers is None:
        return [draw(job) for job in jobs]
    helpers.next_figure.value = 0
    order = sorted(range(len(jobs)), key=lambda k: not isinstance(jobs[k], CandidatesFigure))  # the slowest first
    queue = [jobs[k] for k in order]
    offered = []
    try:
        offered += [helpers.pool.submit(_drain, queue) for _ in range(helpers.size)]
    except BrokenExecutor:  # a helper died earlier: no more help
        pass
    drawn: dict[int, bytes] = {}
    for future in offered:
        try:
            drawn.update({order[k]: png for k, png in future.result().items()})
        except BrokenExecutor:
            pass
    return [drawn[k] if k in drawn else draw(job) for k, job in enumerate(jobs)]
