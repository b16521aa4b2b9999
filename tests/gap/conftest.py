"""Fixtures of the gap tests: short synthetic datasets from the rig simulator (a few seconds each)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from grader.model.effects import EffectSet
from grader.model.linear import plant_coeffs
from grader.model.params import Controller, RigParams
from grader.model.sampled import discrete_critical_gain
from grader.stations import Station
from grader.synth import RunPlan, make_dataset

SIGMA = 0.0004  # [in], the default station's position noise
MakeDataset = Callable[..., Path]


def seen_without_b(rig: RigParams) -> RigParams:
    """The frictionless loop with ``rig``'s three plant coefficients: what runs fitted without B see. With B = 0,
    X/I = b0 / (s (s² + a2 s + a1)) has a1 = g·A²/M, a2 = g·Kce, b0 = g·Kq·A/M (g = 4β/Vt)."""
    a2, a1, b0 = plant_coeffs(rig)
    g = a1 * rig.M / rig.A**2
    return rig.with_(B=0.0, beta_over_Vt=g / 4, Kce=a2 / g, Kq=b0 * rig.M / (g * rig.A))


def short_plan(station: Station) -> list[RunPlan]:
    """The paper's six runs, shortened to about 1 s; the instability run 3 % past the linear critical gain."""
    k_unstable = float(np.ceil(discrete_critical_gain(station.params()) * 1.03))
    return [
        RunPlan("step_kp10", "step", Controller(10), duration=1.0),
        RunPlan("step_kp25", "step", Controller(25), duration=1.0),
        RunPlan("step_kp46", "step", Controller(46), duration=1.0),
        RunPlan("instability", "instability", Controller(k_unstable), duration=1.2),
        RunPlan("ramp_p", "ramp", Controller(10), amplitude=1.0, duration=1.0),
        RunPlan("ramp_pi", "ramp", Controller(10, Ki=20), amplitude=1.0, duration=1.0),
    ]


@pytest.fixture(scope="session")
def make(tmp_path_factory: pytest.TempPathFactory, station: Station) -> MakeDataset:
    """``make(name, effects={...}, seed=...)``: a short rig dataset with sensor noise and ``effects``."""
    cache: dict[str, Path] = {}

    def build(name: str, effects: dict[str, dict[str, float]] | None = None, seed: int = 5) -> Path:
        if name not in cache:
            eff = EffectSet({"sensor_noise": {"sigma": SIGMA}, **(effects or {})})
            cache[name] = make_dataset(station, tmp_path_factory.mktemp(name) / name, seed=seed, runs=short_plan(station),
                                       effects=eff)
        return cache[name]

    return build


FEW = ("coulomb_friction", "valve_deadband", "sampling_delay", "viscous_friction")


@pytest.fixture(scope="session")
def analysed(make: MakeDataset) -> Callable[..., object]:
    """``analysed(name, effects=..., seed=...)``: the cached analysis of ``make(name, ...)`` with the FEW candidates."""
    from grader.gap.diagnose import analyse

    cache: dict[str, object] = {}

    def run(name: str, effects: dict[str, dict[str, float]] | None = None, seed: int = 5) -> object:
        if name not in cache:
            cache[name] = analyse(make(name, effects, seed), effects=FEW)
        return cache[name]

    return run


def _drop_u(folder: Path) -> Path:
    """``folder``'s dataset with every run's u column (the recorded controller output) dropped, in place."""
    import csv

    for f in folder.glob("*.csv"):
        rows = list(csv.reader(f.read_text(encoding="utf-8").splitlines()))
        if rows and rows[0][-1].startswith("u "):
            f.write_text("\n".join(",".join(r[:-1]) for r in rows) + "\n", encoding="utf-8")
    return folder


@pytest.fixture
def without_u() -> Callable[[Path], Path]:
    """Drops the u column of a dataset's runs (nothing can then be replayed)."""
    return _drop_u
