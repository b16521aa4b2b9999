"""One-sample glitches in a run's position reading, found and mended before the diagnosis compares it.

A logger glitch is one reading far from both its neighbours, on the same side of each: the reading
jumps out and back within one sample. A reading is taken as one (:func:`find_glitches`) where its
smaller jump to either neighbour is more than

* :data:`JUMP_TIMES` times the largest jump between any other two successive readings of the run:
  beyond anything the rig's motion does in one sample (a ringing step sampled eight times a period
  jumps as far as it bends, so no test of smoothness around the reading would do), and
* :data:`COUNT_TIMES` times the smallest step between two readings: a quantised reading that
  flickers by a count is data, not a glitch.

A motion's corner (a step starting) jumps to one side only and is never one. At most :data:`MOST`
glitches are found in a run. A glitch is compared as
the mean of its two neighbours, with a note naming the row: left in, a 5 in spike reads as an
800 % overshoot and inflates the noise floor.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from grader.datasets import Run

Array = NDArray[np.float64]
JUMP_TIMES = 3.0
COUNT_TIMES = 3.0
#: Most glitches mended in one run.
MOST = 3


def find_glitches(y: Array) -> list[int]:
    """Indices of the one-sample glitches of the reading ``y``, in order (see module docstring): the most, up to
    :data:`MOST`, of the largest same-side jumps that each exceed the thresholds once the jumps of all of them
    are left out of "any other"."""
    if y.size < 4:
        return []
    d = np.diff(y)
    out, back = d[:-1], -d[1:]  # reading k = 1..n-2: y_k - y_(k-1) and y_k - y_(k+1)
    jump = np.where(np.sign(out) == np.sign(back), np.minimum(np.abs(out), np.abs(back)), 0.0)
    steps = np.abs(d)
    top = np.argsort(-jump, kind="stable")[:MOST]
    for m in range(top.size, 0, -1):
        k = top[:m]
        others = np.delete(steps, np.concatenate([k, k + 1]))
        least = float(np.min(others[others > 0])) if np.any(others > 0) else 0.0
        if others.size and np.all(jump[k] > max(JUMP_TIMES * float(np.max(others)), COUNT_TIMES * least)):
            return sorted(int(i) + 1 for i in k)
    return []


def mend(run: Run) -> tuple[Run, list[str]]:
    """The run with each glitch of its reading replaced by the mean of its neighbours, and a note per glitch
    naming its CSV row (the header is row 1), time [s] and size [in]."""
    found = find_glitches(run.y)
    if not found:
        return run, []
    y = run.y.copy()
    notes = []
    for k in found:
        y[k] = 0.5 * (run.y[k - 1] + run.y[k + 1])
        notes.append(f"run {run.name} ({run.spec.file}): the reading at row {k + 2} (t = {run.t[k]:.6g} s) lies "
                     f"{run.y[k] - y[k]:+.3g} in off its neighbours and back within one sample, more than three "
                     "times any other step of the run: a logger glitch, compared as the mean of its neighbours")
    return replace(run, y=y), notes
