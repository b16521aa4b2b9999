"""The fit objective: step and ramp runs sample by sample, the instability run's oscillation without its phase;
and the spread that the reading noise gives a model's own runs."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from grader.gap.backend import Point
from grader.gap.metrics import nrmse
from grader.gap.objective import RunObjective, objective
from grader.gap.runs import GapRun
from grader.gap.spread import spread
from grader.model.effects import EffectSet
from grader.model.params import Controller
from grader.stations import load_station

T = 0.001
START = 0.1


def _oscillation(amp: float = 0.02, freq: float = 30.0, phase: float = 0.0, growth: float = 0.0,
                 duration: float = 1.5) -> np.ndarray:
    t = np.arange(0.0, duration, T)
    tau = np.clip(t - START, 0.0, None)
    return np.where(t >= START, 0.2 + amp * np.exp(growth * tau) * np.sin(2 * np.pi * freq * tau + phase), 0.0)


def _run(y: np.ndarray, kind: str = "instability") -> GapRun:
    t = np.arange(y.size) * T
    r = np.where(t >= START, 0.2, 0.0)
    return GapRun("run", kind, Controller(50), t, r, y, None, START, float(np.std(y)), np.zeros(y.size))


@settings(max_examples=25, deadline=None)
@given(scale=st.floats(0.5, 1.5), shift=st.floats(-0.01, 0.01))
def test_a_step_runs_residual_is_its_nrmse(scale: float, shift: float) -> None:
    y = _oscillation(amp=0.0) * (1 - np.exp(-np.arange(1500) * T * 20))
    run = _run(y, "step")
    x = y * scale + shift
    assert np.linalg.norm(objective(run).residual(x)) == pytest.approx(nrmse(y, x), rel=1e-9)


def test_the_oscillation_is_compared_without_its_phase() -> None:
    obj = objective(_run(_oscillation()))
    assert obj.k0 < 300 and obj.mean.size > 5  # onset sample by sample, then windows
    own = np.linalg.norm(obj.residual(_oscillation()))
    # half a period out of phase after the onset: sample by sample that is the whole oscillation, here nothing
    late = _oscillation()
    late[obj.k0:] = _oscillation(phase=np.pi)[obj.k0:]
    assert np.linalg.norm(obj.residual(late)) < 0.02
    assert nrmse(_oscillation(), late) > 0.5
    assert own < 1e-9


def test_frequency_and_amplitude_errors_cost_in_proportion() -> None:
    obj = objective(_run(_oscillation()))
    costs = [np.linalg.norm(obj.residual(_oscillation(freq=30.0 * (1 + e)))) for e in (0.005, 0.01, 0.02)]
    assert costs[0] < costs[1] < costs[2]
    assert costs[2] / costs[1] == pytest.approx(2.0, rel=0.25)
    smaller = np.linalg.norm(obj.residual(_oscillation(amp=0.015)))
    assert smaller > 0.01
    stable = np.linalg.norm(obj.residual(_oscillation(growth=-20.0)))  # a model whose oscillation dies out
    assert stable > smaller


def test_cut_is_the_objective_of_the_cut_run() -> None:
    y = _oscillation()
    obj = objective(_run(y))
    short = obj.cut(0.4)
    assert isinstance(short, RunObjective) and short.run.n < obj.run.n
    x = _oscillation(freq=31.0)
    full = obj.residual(x)
    part = short.residual(x[:short.run.n])
    m = short.mean.size
    # the cut keeps the onset and the first windows of the whole run's comparison (normalised by its own length)
    norm = np.sqrt(obj.run.n / short.run.n)
    assert np.allclose(part[:short.k0], full[:short.k0] * norm)
    # (the smoothing's edge at the cut moves the last window's mean a little)
    assert np.allclose(part[short.k0:short.k0 + m], full[obj.k0:obj.k0 + m] * norm, rtol=0.02)


def test_readings_noise_does_not_read_as_amplitude() -> None:
    clean = _oscillation(amp=0.01)
    draws = [clean + np.random.default_rng(seed).normal(0.0, 0.004, clean.size) for seed in range(8)]
    corrected = np.mean([objective(_run(y), sigma=0.004).amp for y in draws])
    raw = np.mean([objective(_run(y)).amp for y in draws])
    ref = np.mean(objective(_run(clean)).amp)
    assert corrected == pytest.approx(ref, rel=0.015)
    assert raw > 1.03 * ref  # what the correction takes out


def test_a_backlash_makes_the_model_wander_with_the_noise_a_linear_model_does_not(make) -> None:  # noqa: ANN001
    from grader.datasets import load
    from grader.gap.runs import prepare_runs

    ds = load(make("quiet"))
    runs = prepare_runs(ds, ds.given["sample_time"])[1]
    objs = [objective(r, 0.0004) for r in runs]
    p = load_station("default").params()
    linear = spread(objs, Point(p), 0.0004)
    backlash = spread(objs, Point(p, EffectSet({"valve_hysteresis": {"width": 1.5}})), 0.0004)
    noise = np.array([(0.0004 / r.scale) ** 2 for r in runs])
    assert np.all(linear < 0.5 * noise)
    steps = [i for i, r in enumerate(runs) if r.kind == "step"]
    assert np.max(backlash[steps]) > 2.0 * np.max(noise[steps])
    assert np.array_equal(spread(objs, Point(p), 0.0004), linear)  # fixed seeds: the same every time
