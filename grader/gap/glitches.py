"""One-sample glitches in a run's position reading, found and mended before the diagnosis compares it.

A logger glitch is one reading that jumps out and back within one sample: far from both its
neighbours, on the same side of each, while they agree with each other to within a third of that
jump (a reading that follows a step within one sample and overshoots for one does not come back, and
is never one). The first or last reading is one where its step to its only neighbour is the jump and
the run goes on from that neighbour in steps under a third of it. A reading is taken as one
(:func:`search`) where its jump is more than

* :data:`JUMP_TIMES` times the largest step between any other two successive readings of the run
  (the steps next to the :data:`SEEN` largest candidates left out): beyond anything the rig's motion
  does in one sample (a ringing step sampled eight times a period jumps as far as it bends, so no
  test of smoothness around the reading would do), and
* :data:`COUNT_TIMES` times the smallest of those steps: a quantised reading that flickers by a
  count is data, not a glitch.

Candidates are mended largest first, each tested again on the reading as mended so far (the clean
reading between two glitches one sample apart looks like a dip until the first is mended). A glitch
is compared as the mean of its two neighbours (at an end, as its neighbour), with a note naming the
row: left in, a 5 in spike reads as an 800 % overshoot and inflates the noise floor. More than
:data:`MOST` glitches in a run are a fault of the sensor or its wiring, not glitches: none is mended,
and the note says so.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]
JUMP_TIMES = 3.0
COUNT_TIMES = 3.0
#: Most glitches mended in one run.
MOST = 3
#: Candidates whose steps are left out of "any other step".
SEEN = 2 * MOST


@dataclass(frozen=True)
class Glitches:
    """What :func:`search` found: the glitches' indices (in order), the reading [in] with each mended, and whether
    more readings passed the bar than the candidates looked at (:data:`SEEN`)."""

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


def _mend_one(y: Array, k: int) -> None:
    y[k] = y[1] if k == 0 else y[-2] if k == y.size - 1 else 0.5 * (y[k - 1] + y[k + 1])


def search(y: Array) -> Glitches:
    """Every glitch of the reading ``y`` [in] (module docstring), however many."""
    if y.size < 4:
        return Glitches((), y)
    jump, steps = jumps(y), np.abs(np.diff(y))
    top = [int(k) for k in np.argsort(-jump, kind="stable")[:SEEN] if jump[k] > 0]
    others = np.delete(steps, sorted({s for k in top for s in (k - 1, k) if 0 <= s < steps.size}))
    if others.size == 0:
        return Glitches((), y)
    moving = others[others > 0]
    bar = max(JUMP_TIMES * float(np.max(others)), COUNT_TIMES * float(np.min(moving)) if moving.size else 0.0)
    mended, found = y.copy(), []
    for k in top:
        if jumps(mended)[k] > bar:
            found.append(k)
            _mend_one(mended, k)
    return Glitches(tuple(sorted(found)), mended, bool(found) and bool(np.any(jumps(mended) > bar)))


def find_glitches(y: Array) -> list[int]:
    """Indices of the glitches of ``y`` to mend: none where there are more than :data:`MOST`."""
    g = search(y)
    return [] if g.too_many else list(g.found)


def mend(y: Array, t: Array, where: str) -> tuple[Array, list[str], list[int]]:
    """The reading ``y`` [in] at times ``t`` [s] with its glitches mended, a note on each (``where`` names the run
    and file) and their CSV rows (a reading's index + 2); where there are too many, ``y`` as it is, one note and
    no rows."""
    g = search(y)
    if not g.found:
        return y, [], []
    size = y - g.mended
    if g.too_many:
        rows = ", ".join(str(k + 2) for k in g.found[:MOST + 1])
        return y, [f"{where}: {'more than ' if g.more else ''}{len(g.found)} readings jump out and back within one "
                   f"sample (rows {rows}{', …' if len(g.found) > MOST + 1 or g.more else ''}; up to "
                   f"{np.max(np.abs(size)):.3g} in): more than {MOST} is a fault of the sensor or its wiring, not a "
                   "logger's glitch; they are compared as recorded"], []
    return (g.mended, [_note(where, k, t[k], float(size[k]), end=k in (0, y.size - 1)) for k in g.found],
            [k + 2 for k in g.found])


def _note(where: str, k: int, t: float, size: float, *, end: bool) -> str:
    off = "its neighbour (it ends the run)" if end else "its neighbours and back within one sample"
    return (f"{where}: the reading at row {k + 2} (t = {t:.6g} s) lies {size:+.3g} in off {off}, more than "
            f"{JUMP_TIMES:g} times any other step of the run: a logger glitch, compared as "
            f"{'its neighbour' if end else 'the mean of its neighbours'}")
