"""Synthetic lab datasets from a station definition (fixtures, demo, benchmarks, diagnosis data).

Static tests (pot calibration, flow test, friction data) are generated from the
station's truth with the effects that show in them (valve saturation, hysteresis
and deadband in the flow test; Coulomb and viscous friction in the friction data).
Closed-loop runs come from the nonlinear rig simulator when an :class:`EffectSet`
is given (:func:`make_dataset`'s ``effects``), else from a :data:`RunSimulator`,
by default the linear sampled-loop model plus the station's position noise.
The effects used are written to ``truth.json`` (see :class:`TruthFile`), never to
the manifest, so a dataset can be handed on with its effects withheld.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, ValidationError

from grader import __version__
from grader.datasets import ControllerSpec, Manifest, RunSpec, write_dataset
from grader.datasets.schema import RunKind
from grader.errors import DatasetError, SimulationError, validation_message
from grader.identify.oscillation import sustained as lasting
from grader.model.effects import EffectSet
from grader.model.params import Controller, RigParams
from grader.model.rig import simulate_rig, simulate_rig_batch
from grader.model import zloop
from grader.model.sampled import simulate
from grader.stations import Station, station_effects  # noqa: F401 - station_effects is part of synth's API

Array = NDArray[np.float64]
#: (params, controller, t [s], r [in], rng) -> (y [in], u [V]) without measurement noise
RunSimulator = Callable[[RigParams, Controller, Array, Array, np.random.Generator], tuple[Array, Array]]
TRUTH_FILE = "truth.json"
INSTABILITY_STEP = 0.2  # [in] on the rig: the same step as the other step runs


def linear_runs(p: RigParams, c: Controller, t: Array, r: Array, rng: np.random.Generator) -> tuple[Array, Array]:
    """The reference linear model as a run simulator (no unmodelled effects)."""
    res = simulate(p, c, t, r)
    return res.y, res.u


def rig_runs(effects: EffectSet) -> RunSimulator:
    """The nonlinear rig with ``effects`` as a run simulator (noise drawn from the run's rng)."""

    def run(p: RigParams, c: Controller, t: Array, r: Array, rng: np.random.Generator) -> tuple[Array, Array]:
        return simulate_rig(p, c, t, r, effects, rng=rng)

    return run


@dataclass(frozen=True)
class RunPlan:
    """One run to record: name, kind, gains, command shape and duration."""

    name: str
    kind: RunKind
    controller: Controller
    amplitude: float = 0.2  # step size [in] or ramp rate [in/s]
    duration: float = 1.5  # [s]
    start: float = 0.1  # command starts [s]


#: Draws of the reading noise under which a gain's oscillation must last (see :func:`instability_gain`).
NOISE_DRAWS = 3


def instability_gain(p: RigParams, effects: EffectSet, *, duration: float = 2.0,
                     run_simulator: RunSimulator | None = None) -> float:
    """The P gain (volts convention, on a 0.5 grid) at which the rig's step response first
    oscillates without decaying: the gain raised slowly until the system goes unstable, as
    students do. The search sees the rig's noise (:data:`NOISE_DRAWS` draws from fixed seeds, so
    the gain is reproducible, and the oscillation must last in every one): near the critical gain
    noise can stop an oscillation that friction barely lets grow, and a student would raise the
    gain further (a gain that lasted under one draw of the noise died out under another 2 times
    in 60 random rigs). If no gain up to 3x the linear critical gain
    is unstable, that bound is returned. With ``run_simulator`` (another rig: the benchmark's
    independent solve_ivp path, its noise included), that rig decides (:func:`_decided_by`): this
    search's gain is only where it starts."""
    t = np.round(np.arange(0.0, duration + 1e-9, p.sample_time), 9)
    r = np.where(t >= 0.1, INSTABILITY_STEP, 0.0)
    scale = 1.0 if p.feedback == "volts" else p.Kpot
    if run_simulator is not None:
        guess = instability_gain(p, effects, duration=duration)
        return _decided_by(run_simulator, p, t, r, guess, step=float(max(1.0, np.ceil(0.05 * guess))))

    def first_unstable(gains: Array) -> float | None:
        sustained = np.ones(gains.size, dtype=bool)
        for seed in range(NOISE_DRAWS):
            y, _ = simulate_rig_batch(p, [Controller(float(k) * scale) for k in gains], t, r, effects,
                                      rng=np.random.default_rng(seed))
            sustained &= lasting(y, t, 0.1, INSTABILITY_STEP)
        unstable = np.flatnonzero(sustained)
        return float(gains[unstable[0]]) if unstable.size else None

    k_lin = zloop.critical_gain(p) / scale  # native convention -> volts convention
    step = float(max(1.0, np.ceil(0.05 * k_lin)))
    coarse = np.arange(max(0.5, np.floor(0.2 * k_lin)), 3.0 * k_lin + step, step)
    first = first_unstable(coarse)
    if first is None:
        return float(coarse[-1])
    return first_unstable(np.arange(max(first - step + 0.5, 0.5), first, 0.5)) or first


def _decided_by(sim: RunSimulator, p: RigParams, t: Array, r: Array, guess: float, *, step: float) -> float:
    """The first gain (volts convention) on the 0.5 grid at which ``sim``'s rig oscillates without decaying under
    every one of :data:`NOISE_DRAWS` noise draws, searched from ``guess``: down in steps of 0.5 while the gain below
    still lasts; else up in coarse ``step`` until one lasts (at most to 3x ``guess``, returned if none does), then
    back down in steps of 0.5."""
    scale = 1.0 if p.feedback == "volts" else p.Kpot

    def lasts(k: float) -> bool:
        return all(lasting(sim(p, Controller(k * scale), t, r, np.random.default_rng(seed))[0][None, :], t, 0.1,
                           INSTABILITY_STEP)[0]
                   for seed in range(NOISE_DRAWS))

    k = guess
    if not lasts(k):
        while not lasts(k := k + step):
            if k >= 3.0 * guess:
                return k
    while k - 0.5 >= 0.5 and lasts(k - 0.5):
        k -= 0.5
    return k


def paper_runs(p: RigParams, effects: EffectSet | None = None, *,
               run_simulator: RunSimulator | None = None) -> list[RunPlan]:
    """The paper's procedure: steps at Kp = 10, 25, 46, the instability run, and P and PI ramps.
    Gains are in the volts convention, scaled by 1/Kpot for the inches convention. The
    instability gain is found on the rig (:func:`instability_gain`) when ``effects`` are given,
    else it is the sampled linear loop's critical gain plus 1.5 % (with a 0.05 in step; the rig's
    instability run steps 0.2 in, as Coulomb friction damps small oscillations out); ``run_simulator``
    decides it on another rig (see :func:`instability_gain`)."""
    scale = 1.0 if p.feedback == "volts" else p.Kpot
    if effects is None:
        k_crit = zloop.critical_gain(p) / scale  # native convention -> volts convention
        k_unstable, step = float(np.ceil(k_crit * 1.015 * 2) / 2), 0.05
    else:
        k_unstable, step = instability_gain(p, effects, run_simulator=run_simulator), INSTABILITY_STEP
    return [
        RunPlan("step_kp10", "step", Controller(10 * scale)),
        RunPlan("step_kp25", "step", Controller(25 * scale)),
        RunPlan("step_kp46", "step", Controller(46 * scale)),
        RunPlan("instability", "instability", Controller(k_unstable * scale), amplitude=step, duration=2.0),
        RunPlan("ramp_p", "ramp", Controller(10 * scale), amplitude=1.0),
        RunPlan("ramp_pi", "ramp", Controller(10 * scale, Ki=20 * scale), amplitude=1.0),
    ]


def _command(plan: RunPlan, t: Array) -> Array:
    on = t >= plan.start
    if plan.kind == "ramp":
        return np.where(on, plan.amplitude * (t - plan.start), 0.0)
    return np.where(on, plan.amplitude, 0.0)


def flow_test_current(i: Array, effects: EffectSet, flow_saturation: float) -> Array:
    """Current [mA] the spool acts on in the flow test's rising sweep ``i`` [mA]: saturation
    (``valve_saturation`` or the station's flow_saturation), backlash (the valve was last moved
    down to the sweep's start), then deadband."""
    sat = effects.value("valve_saturation", "i_max") if "valve_saturation" in effects else flow_saturation
    i = np.clip(i, -sat, sat)
    if "valve_hysteresis" in effects:
        half = effects.value("valve_hysteresis", "width") / 2
        i = np.maximum(i[0] + half, i - half)
    if "valve_deadband" in effects:
        half = effects.value("valve_deadband", "width") / 2
        i = np.sign(i) * np.maximum(np.abs(i) - half, 0.0)
    return i


def _static_tables(station: Station, effects: EffectSet, rng: np.random.Generator) -> dict[str, dict[str, tuple[str, Array]]]:
    tr, nz, g = station.truth_values(), station.noise_values(), station.given.values()
    pos = np.arange(0.0, 4.01, 0.5)
    volts = tr["pot_offset"] + tr["Kpot"] * pos + rng.normal(0, nz["voltage"], pos.size)
    v_in = np.arange(-10.0, 10.01, 0.5)
    q = tr["Kq"] * flow_test_current(g["Kamp"] * v_in - tr["null_offset"], effects, tr["flow_saturation"])
    reading = np.abs(q) + tr["leakage"] + rng.normal(0, nz["flow"], v_in.size)
    speed = np.array([0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 5.0, 6.0])
    fc = effects.value("coulomb_friction", "Fc") if "coulomb_friction" in effects else 0.0
    b = tr["B"] + (effects.value("viscous_friction", "B") if "viscous_friction" in effects else 0.0)
    force = fc + b * speed + rng.normal(0, nz["force"], speed.size)
    gpm = 231.0 / 60.0  # in³/s per gpm
    return {
        "calibration.csv": {"position": ("in", pos), "voltage": ("V", volts)},
        "flow.csv": {"input": ("V", v_in), "flow": ("gpm", np.abs(reading) / gpm)},
        "friction.csv": {"speed": ("in/s", speed), "force": ("lbf", np.abs(force))},
    }


class TruthFile(BaseModel):
    """``truth.json`` beside a synthetic dataset: what the simulator put in (never in the manifest)."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    format: Literal["grader-truth/1"] = "grader-truth/1"
    station: str
    seed: int
    grader_version: str
    simulator: Literal["rig", "linear"]
    effects: dict[str, dict[str, str]]

    def effect_set(self) -> EffectSet:
        return EffectSet.from_quantities(self.effects)


def read_truth(folder: str | Path) -> TruthFile:
    """Read and validate ``truth.json`` in a dataset folder."""
    path = Path(folder) / TRUTH_FILE
    if not path.is_file():
        raise DatasetError(f"{path}: no {TRUTH_FILE} (only synthetic datasets have one)")
    try:
        truth = TruthFile.model_validate(json.loads(path.read_text(encoding="utf-8")))
        truth.effect_set()
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise DatasetError(f"{path.name}: not valid JSON ({exc})") from None
    except ValidationError as exc:
        raise DatasetError(validation_message(path.name, exc)) from None
    except SimulationError as exc:
        raise DatasetError(f"{path.name}: {exc}") from None
    return truth


def make_dataset(
    station: Station,
    out: str | Path,
    *,
    seed: int = 0,
    runs: list[RunPlan] | None = None,
    run_simulator: RunSimulator | None = None,
    effects: EffectSet | None = None,
) -> Path:
    """Write a complete lab dataset for ``station`` into folder ``out``, with ``truth.json``.

    With ``effects`` the runs come from the rig simulator (noise included as the
    ``sensor_noise`` effect, the controller sees it); else from ``run_simulator``
    (default: the linear model) plus the station's position noise on the record.
    """
    if effects is not None and run_simulator is not None:
        raise SimulationError("make_dataset: give effects (rig simulator) or run_simulator, not both")
    rng = np.random.default_rng(seed)
    p = station.params()
    tables = _static_tables(station, effects if effects is not None else station_effects(station), rng)
    simulator = rig_runs(effects) if effects is not None else (run_simulator or linear_runs)
    sigma = station.noise_values()["position"]
    specs = []
    for plan in runs if runs is not None else paper_runs(p, effects):
        t = np.round(np.arange(0.0, plan.duration + 1e-9, p.sample_time), 9)
        r = _command(plan, t)
        y, u = simulator(p, plan.controller, t, r, rng)
        if effects is None:
            y = y + rng.normal(0.0, sigma, t.size)
        tables[f"{plan.name}.csv"] = {"t": ("s", t), "r": ("in", r), "y": ("in", y), "u": ("V", u)}
        c = plan.controller
        specs.append(RunSpec(name=plan.name, file=f"{plan.name}.csv", kind=plan.kind,
                             controller=ControllerSpec(Kp=c.Kp, Ki=c.Ki, Kd=c.Kd)))
    manifest = Manifest(
        station=station.station, given=station.given, feedback=station.feedback,
        calibration="calibration.csv", flow_test="flow.csv", friction="friction.csv", runs=specs,
    )
    root = write_dataset(out, manifest, tables)
    truth = TruthFile(station=station.station, seed=seed, grader_version=__version__,
                      simulator="rig" if effects is not None else "linear",
                      effects=(effects or EffectSet()).to_quantities())
    (root / TRUTH_FILE).write_text(json.dumps(truth.model_dump(mode="json"), indent=2) + "\n", encoding="utf-8")
    return root
