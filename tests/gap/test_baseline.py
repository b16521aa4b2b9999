"""The diagnosis' linear baseline when the instability run cannot be read."""

from __future__ import annotations

import numpy as np

from grader.gap.baseline import _oscillation
from grader.gap.runs import GapRun
from grader.model.params import Controller
from grader.stations import load_station

from .conftest import MakeDataset


def _instability(cycles_alive: float) -> GapRun:
    """A 25 Hz oscillation after a 0.1 in step at 0.1 s that friction stops after ``cycles_alive`` cycles."""
    t = np.arange(0.0, 1.5, 0.001)
    tau = np.clip(t - 0.1, 0.0, None)
    alive = np.clip(1.0 - tau * 25.0 / cycles_alive, 0.0, None)
    y = np.where(t >= 0.1, 0.1 + 0.01 * alive * np.sin(2 * np.pi * 25 * tau), 0.0)
    y = np.round(y / 0.0005) * 0.0005  # a coarse ADC: the dead tail sits on one count
    r = np.where(t >= 0.1, 0.1, 0.0)
    return GapRun("instability", "instability", Controller(60), t, r, y, None, 0.1, float(np.std(y)), np.zeros(t.size))


def test_an_oscillation_that_dies_out_gives_the_typical_start_and_says_why() -> None:
    p = load_station("default").params()
    start, why = _oscillation([_instability(4)], p)
    assert start is None and why.startswith("typical β/Vt and Kce (the instability run shows")
    assert "fewer than 8" in why


def test_a_lasting_oscillation_is_read() -> None:
    p = load_station("default").params()
    start, why = _oscillation([_instability(1e9)], p)
    assert why == "oscillation of run instability at Kp = 60"
    assert start is not None and start.beta_over_Vt != p.beta_over_Vt and start.Kce != p.Kce


def test_the_diagnosis_starts_from_the_baseline_as_written(make: MakeDataset) -> None:
    """Identification leaves last-digit differences between BLAS kernels; the search starts from the values at
    the 6 significant digits diagnosis.json writes, the same on any CPU."""
    from grader.datasets import load
    from grader.gap.baseline import _IDENTIFIED, choose
    from grader.gap.runs import prepare_runs
    from grader.precision import round_sig

    ds = load(make("coulomb_friction", {"coulomb_friction": {"Fc": 2.0}}))
    base = choose(ds, prepare_runs(ds, ds.given["sample_time"])[1], key=None, implied_kfb=None)
    assert base.source == "identified"
    values = [float(getattr(base.params, name)) for name in _IDENTIFIED]
    assert values == [round_sig(v) for v in values] and any(v != round(v, 3) for v in values)
