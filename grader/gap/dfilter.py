"""Runs whose controller filters its derivative: set aside, with a note.

The model's digital controller takes the derivative as the error's first difference over T
(:func:`grader.gap.runs.control_law`). Many lab controllers filter it (Simulink's PID block does by
default): a first-order filter of time constant τf on that difference, d_k = a·d_{k−1} + (1 − a)·(e_k −
e_{k−1})/T with a = τf/(τf + T). Where the recorded u follows the manifest's gains through such a filter
clearly better than without one (the unfiltered law misses u by at least :data:`CLEARLY` times as much,
and the filter moves u by at least the resolution u was printed with), the model cannot reproduce the
run's controller. Simulated unfiltered, such runs (one whose filter moved u by 1 % of its RMS
among them) led an independent simulator's diagnoses astray (a rig with no effect called valve
saturation, Coulomb friction called none) or had the gains refused as wrong (u 0.88 times the
manifest's law). So the run is set aside with a note, as long as
:data:`~grader.gap.runs.MIN_RUNS` others are left; else it is kept, with a note, and its gains are not
checked against u.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import NDArray
from scipy.signal import lfilter

from grader.datasets import Dataset
from grader.gap.runs import MIN_RUNS, GapRun, control_law, controller_gain, seen_reading, u_resolution
from grader.model.rig_setup import DAC_LIMIT

Array = NDArray[np.float64]
#: Filter poles a tried: τf from 0.05 to 19 sample times.
POLES = tuple(round(0.05 * i, 2) for i in range(1, 20))
#: The unfiltered law must miss u by at least this many times the filtered one's mean |error|.
CLEARLY = 2.0


def derivative_filter(run: GapRun, T: float, k_fb: float) -> float | None:
    """τf [s] of the derivative filter through which the recorded u follows the manifest's gains (module
    docstring), or None: no u, no derivative term, or u follows the unfiltered law about as well."""
    c = run.controller
    if run.u is None or c.Kd == 0 or (y := seen_reading(run, T)) is None:
        return None
    e = k_fb * (run.r - y)
    use = np.abs(run.u) < 0.95 * DAC_LIMIT
    if use.sum() < 20:
        return None
    rest = control_law(replace(c, Kd=0.0), e, T)  # the P and I terms, as the model's controller takes them
    diff = np.diff(e, prepend=0.0) / T
    terms = {a: c.Kd * lfilter([1.0 - a], [1.0, -a], diff) for a in (0.0, *POLES)}
    miss = {a: float(np.mean(np.abs(run.u - rest - d)[use])) for a, d in terms.items()}
    best = min(POLES, key=miss.__getitem__)
    moved = float(np.sqrt(np.mean((terms[0.0] - terms[best])[use] ** 2)))
    if miss[0.0] < CLEARLY * miss[best] or moved < u_resolution(run.u):
        return None
    return best / (1.0 - best) * T


def _reference(runs: list[GapRun], k_fb: float | None, T: float) -> float | None:
    """k_fb known without the runs, else the median the runs without a derivative term imply."""
    if k_fb is not None:
        return k_fb
    implied = [k for r in runs if r.controller.Kd == 0 and (k := controller_gain(r, T)) is not None]
    return float(np.median(implied)) if implied else None


def set_aside(ds: Dataset, runs: list[GapRun], k_fb: float | None, T: float
              ) -> tuple[Dataset, list[GapRun], list[str], frozenset[str]]:
    """The dataset and runs without those whose controller filters its derivative (module docstring), a note for
    each, and the names of such runs kept (too few others to set them aside): their gains go unchecked."""
    ref = _reference(runs, k_fb, T)
    found = {} if ref is None else {r.name: tau for r in runs if (tau := derivative_filter(r, T, ref)) is not None}
    if not found:
        return ds, runs, [], frozenset()
    keep = len(runs) - len(found) < MIN_RUNS
    then = "too few other runs to set it aside: it is compared as the model simulates it" if keep else \
        "the run is set aside"
    notes = [f"run {name}: its recorded controller output u follows the manifest's gains with the derivative "
             f"filtered (time constant about {tau * 1e3:.2g} ms, {tau / T:.2g} samples), which the model's controller "
             f"does not filter; {then}" for name, tau in found.items()]
    if keep:
        return ds, runs, notes, frozenset(found)
    return (replace(ds, runs=tuple(r for r in ds.runs if r.name not in found)),
            [r for r in runs if r.name not in found], notes, frozenset())
