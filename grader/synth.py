"""Synthetic lab datasets from a station definition (fixtures, demo, benchmarks).

Static tests (pot calibration, flow test, friction data) are generated here from
the station's truth; closed-loop runs come from a :data:`RunSimulator`, by default
the linear sampled-loop model of :mod:`grader.model.sampled`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from grader.datasets import ControllerSpec, Manifest, RunSpec, write_dataset
from grader.model.params import Controller, RigParams
from grader.model.sampled import discrete_critical_gain, simulate
from grader.stations import Station

Array = NDArray[np.float64]
#: (params, controller, t [s], r [in], rng) -> (y [in], u [V]) without measurement noise
RunSimulator = Callable[[RigParams, Controller, Array, Array, np.random.Generator], tuple[Array, Array]]


def linear_runs(p: RigParams, c: Controller, t: Array, r: Array, rng: np.random.Generator) -> tuple[Array, Array]:
    """The reference linear model as a run simulator (no unmodelled effects)."""
    res = simulate(p, c, t, r)
    return res.y, res.u


@dataclass(frozen=True)
class RunPlan:
    """One run to record: name, kind, gains, command shape and duration."""

    name: str
    kind: str
    controller: Controller
    amplitude: float = 0.2  # step size [in] or ramp rate [in/s]
    duration: float = 1.5  # [s]
    start: float = 0.1  # command starts [s]


def paper_runs(p: RigParams) -> list[RunPlan]:
    """The paper's procedure: steps at Kp = 10, 25, 46, the instability run just past the
    sampled loop's critical gain, and P and PI ramps. Gains are in the volts convention
    and scaled by 1/Kpot for the inches convention."""
    scale = 1.0 if p.feedback == "volts" else p.Kpot
    k_unstable = np.ceil(discrete_critical_gain(p) * 1.015 * 2) / 2
    return [
        RunPlan("step_kp10", "step", Controller(10 * scale)),
        RunPlan("step_kp25", "step", Controller(25 * scale)),
        RunPlan("step_kp46", "step", Controller(46 * scale)),
        RunPlan("instability", "instability", Controller(float(k_unstable) * scale), amplitude=0.05, duration=2.0),
        RunPlan("ramp_p", "ramp", Controller(10 * scale), amplitude=1.0),
        RunPlan("ramp_pi", "ramp", Controller(10 * scale, Ki=20 * scale), amplitude=1.0),
    ]


def _command(plan: RunPlan, t: Array) -> Array:
    on = t >= plan.start
    if plan.kind == "ramp":
        return np.where(on, plan.amplitude * (t - plan.start), 0.0)
    return np.where(on, plan.amplitude, 0.0)


def _static_tables(station: Station, rng: np.random.Generator) -> dict[str, dict[str, tuple[str, Array]]]:
    tr, nz, g = station.truth_values(), station.noise_values(), station.given.values()
    pos = np.arange(0.0, 4.01, 0.5)
    volts = tr["pot_offset"] + tr["Kpot"] * pos + rng.normal(0, nz["voltage"], pos.size)
    v_in = np.arange(-10.0, 10.01, 0.5)
    i = g["Kamp"] * v_in - tr["null_offset"]
    q = tr["Kq"] * np.clip(i, -tr["flow_saturation"], tr["flow_saturation"])
    reading = np.abs(q) + tr["leakage"] + rng.normal(0, nz["flow"], v_in.size)
    speed = np.array([0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 5.0, 6.0])
    fc = float(station.effects.get("coulomb_friction", {}).get("Fc", "0 lbf").split()[0])
    force = fc + tr["B"] * speed + rng.normal(0, nz["force"], speed.size)
    gpm = 231.0 / 60.0  # in³/s per gpm
    return {
        "calibration.csv": {"position": ("in", pos), "voltage": ("V", volts)},
        "flow.csv": {"input": ("V", v_in), "flow": ("gpm", np.abs(reading) / gpm)},
        "friction.csv": {"speed": ("in/s", speed), "force": ("lbf", np.abs(force))},
    }


def make_dataset(
    station: Station,
    out: str | Path,
    *,
    seed: int = 0,
    runs: list[RunPlan] | None = None,
    run_simulator: RunSimulator = linear_runs,
) -> Path:
    """Write a complete lab dataset for ``station`` into folder ``out``."""
    rng = np.random.default_rng(seed)
    p = station.params()
    tables = _static_tables(station, rng)
    specs = []
    sigma = station.noise_values()["position"]
    for plan in runs if runs is not None else paper_runs(p):
        t = np.round(np.arange(0.0, plan.duration + 1e-9, p.sample_time), 9)
        r = _command(plan, t)
        y, u = run_simulator(p, plan.controller, t, r, rng)
        y = y + rng.normal(0.0, sigma, t.size)
        file = f"{plan.name}.csv"
        tables[file] = {"t": ("s", t), "r": ("in", r), "y": ("in", y), "u": ("V", u)}
        c = plan.controller
        specs.append(RunSpec(name=plan.name, file=file, kind=plan.kind, controller=ControllerSpec(Kp=c.Kp, Ki=c.Ki, Kd=c.Kd)))
    manifest = Manifest(
        station=station.station, given=station.given, feedback=station.feedback,
        calibration="calibration.csv", flow_test="flow.csv", friction="friction.csv", runs=specs,
    )
    return write_dataset(out, manifest, tables)
