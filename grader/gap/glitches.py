"""One-sample glitches in a run's position reading, found and mended before the diagnosis compares it.

A candidate is a reading that jumps out and back within one sample: far from both its neighbours,
on the same side of each, while they agree with each other to within a third of that jump (a
reading that follows a step within one sample and overshoots for one does not come back, and is
never one); the first or last reading, where its step to its only neighbour is more than three
times the next step (:func:`jumps`). A candidate is a glitch (:func:`search`) where its jump, and
its distance from the median of its four nearest readings, are more than

* :data:`JUMP_TIMES` times the largest step of the run next to no candidate: beyond anything the
  rig's motion does in one sample (a ringing step sampled eight times a period jumps as far as it
  bends, so no test of smoothness around the reading would do; the steps next to candidates are
  left out, so that many glitches do not raise the bar for one another), and
* :data:`COUNT_TIMES` times the smallest nonzero one of those steps: a quantised reading that
  flickers by a count is data, not a glitch.

Glitches are mended one at a time, the one furthest from its four nearest readings' median first
(to that median), each found again on the reading as mended so far: two glitches a sample apart
make the clean reading between them look like a dip, but it lies half as far from its median.
Left in, a 5 in spike reads as an 800 % overshoot and inflates the noise floor. More than
:data:`MOST` glitches in a run are a fault of the sensor or its wiring: none is mended, and the
note says so (the search stops after :data:`SEEN` + 1).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]
JUMP_TIMES = 3.0
COUNT_TIMES = 3.0
#: Most glitches mended in one run.
MOST = 3
#: Most glitches looked for: one more are reported as that many or more.
SEEN = 2 * MOST


@dataclass(frozen=True)
class Glitches:
    """What :func:`search` found: the glitches' indices (in order), the reading [in] with each mended, and whether
    more readings may pass the bar than the :data:`SEEN` + 1 found."""

    found: tuple[int, ...]
    mended: Array
    more: bool = False

    @property
    def too_many(self) -> bool:
        return self.more or len(self.found) > MOST


def jumps(y: Array) -> Array:
    """Each reading's jump [in]: for an interior one, the smaller of its steps to its neighbours where both go the
    same way and the neighbours agree to within 1/:data:`JUMP_TIMES` of it, else 0; for an end, its one step where
    the next step is under 1/:data:`JUMP_TIMES` of it, else 0 (at least 3 readings)."""
    d = np.diff(y)
    out, back = d[:-1], -d[1:]  # reading k = 1..n-2: y_k - y_(k-1) and y_k - y_(k+1)
    jump = np.minimum(np.abs(out), np.abs(back))
    returns = JUMP_TIMES * np.abs(y[2:] - y[:-2]) < jump
    inner = np.where((np.sign(out) == np.sign(back)) & returns, jump, 0.0)
    first = abs(d[0]) if JUMP_TIMES * abs(d[1]) < abs(d[0]) else 0.0  # the run goes on smoothly from the next one
    last = abs(d[-1]) if JUMP_TIMES * abs(d[-2]) < abs(d[-1]) else 0.0
    return np.concatenate([[first], inner, [last]])


def _reference(y: Array) -> Array:
    """Each reading's reference [in]: the median of its four nearest other readings (two on each side, or the next
    four at an end; at least 5 readings). Two glitches a sample apart leave the clean reading between them half as
    far from it as either of them, so the glitches are mended first."""
    k = np.arange(y.size)
    lo = np.clip(k - 2, 0, y.size - 5)
    window = lo[:, None] + np.arange(5)
    near = y[window[window != k[:, None]].reshape(y.size, 4)]
    return np.median(near, axis=1)


def search(y: Array) -> Glitches:
    """Every glitch of the reading ``y`` [in] (module docstring), up to :data:`SEEN` + 1."""
    if y.size < 5:
        return Glitches((), y)
    steps = np.abs(np.diff(y))
    shaped = np.flatnonzero(jumps(y) > 0)
    others = np.delete(steps, np.unique(np.clip(np.concatenate([shaped - 1, shaped]), 0, steps.size - 1)))
    if others.size == 0:
        return Glitches((), y)
    moving = others[others > 0]
    bar = max(JUMP_TIMES * float(np.max(others)), COUNT_TIMES * float(np.min(moving)) if moving.size else 0.0)
    mended, found = y.copy(), []
    while len(found) <= SEEN:
        ref = _reference(mended)
        score = np.where((jumps(mended) > bar) & (np.abs(mended - ref) > bar), np.abs(mended - ref), 0.0)
        k = int(np.argmax(score))
        if score[k] <= 0.0:
            break
        found.append(k)
        mended[k] = ref[k]
    return Glitches(tuple(sorted(found)), mended, len(found) > SEEN)


@dataclass(frozen=True)
class Mended:
    """A reading [in] with its glitches mended (as recorded where there are too many), a note on them, their CSV
    rows (lines in the file), and whether it never changes apart from them."""

    y: Array
    notes: list[str]
    rows: list[int]
    flat: bool


def mend(y: Array, t: Array, where: str, *, line: Callable[[int], int] = lambda k: k + 2) -> Mended:
    """The reading ``y`` [in] at times ``t`` [s] with its glitches mended and a note on each (``where`` names the run
    and file, ``line`` a reading's line in it); where there are too many, ``y`` as recorded and one note."""
    g = search(y)
    rows = [line(k) for k in g.found]
    flat = bool(np.ptp(g.mended) == 0)
    if not g.found:
        return Mended(y, [], [], flat)
    size = y - g.mended
    if g.too_many:
        count = f"{len(g.found)} or more" if g.more else str(len(g.found))
        listed = ", ".join(map(str, rows[:MOST + 1])) + (", …" if len(rows) > MOST + 1 else "")
        return Mended(y, [f"{where}: {count} readings jump out and back within one sample (rows {listed}; up to "
                          f"{np.max(np.abs(size)):.3g} in): more than {MOST} is a fault of the sensor or its wiring, "
                          "not a logger's glitch; they are compared as recorded"], rows, flat)
    notes = [_note(where, row, t[k], float(size[k]), end=k in (0, y.size - 1)) for k, row in zip(g.found, rows)]
    return Mended(g.mended, notes, rows, flat)


def _note(where: str, row: int, t: float, size: float, *, end: bool) -> str:
    off = "its neighbour (it ends the run)" if end else "its neighbours and back within one sample"
    return (f"{where}: the reading at row {row} (t = {t:.6g} s) lies {size:+.3g} in off {off}, more than "
            f"{JUMP_TIMES:g} times any other step of the run: a logger glitch, compared as the median of its four "
            "nearest readings")
