"""PD and PI design checks: on the group's identified model and on the rig simulator.

On the model (the key's sampled-loop model, :mod:`grader.model.zloop`): is the loop
stable; does the design reach its goal (PD cuts the step overshoot of P alone at the same
Kp; PI removes the ramp error P alone leaves); does the claimed overshoot or ramp error
match the simulation. On the rig (:func:`grader.model.rig.simulate_rig_batch` with the
station's true parameters and effects): does the same test settle, or does it limit-cycle
(a sustained oscillation above a threshold) or go unstable (diverges, or oscillates against
the DAC limit). Rig runs are batched: one vectorised simulation for many designs.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from functools import lru_cache
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from grader.errors import GraderError
from grader.grading.answers import DesignAnswer, Gains
from grader.grading.rubric import DesignSpec
from grader.model.effects import EffectSet
from grader.model.params import Controller, RigParams
from grader.model.rig_setup import DAC_LIMIT
from grader.stations import load_station, station_effects, station_file

RigVerdict = Literal["ok", "limit_cycle", "unstable"]
STEP = 0.2  # [in], as in the lab's step runs
RIG_SECONDS = 3.0
RIG_BATCH = 256


@dataclass(frozen=True)
class ModelVerdict:
    """Design on the model: ``achieved`` and ``baseline`` (P alone at the same Kp) are the step
    overshoot [fraction] (PD) or the ramp error [in] (PI); inf when unstable."""

    stable: bool
    achieved: float
    baseline: float
    goal_met: bool
    claim_ok: bool | None


def evaluate_design(item: str, answer: DesignAnswer, p: RigParams, spec: DesignSpec, *, ramp_rate: float) -> ModelVerdict:
    """Simulate ``answer`` on the model ``p`` and judge it against ``spec``."""
    from grader.model import zloop  # scipy.signal and python-control: only when a design is graded

    g = answer.gains
    stable = zloop.is_stable(p, g)
    if item == "pd_design":
        achieved, baseline = zloop.overshoot(p, g), zloop.overshoot(p, Gains(Kp=g.Kp))
        goal = g.Kd > 0 and achieved <= (1.0 - spec.min_reduction) * baseline
        goal = goal and (spec.max_overshoot is None or achieved <= spec.max_overshoot)
    else:
        achieved = zloop.ramp_error(p, g, ramp_rate, spec.ramp_seconds)
        baseline = zloop.ramp_error(p, Gains(Kp=g.Kp), ramp_rate, spec.ramp_seconds)
        goal = g.Ki > 0 and abs(achieved) <= spec.max_ramp_error_fraction * abs(baseline)
    claim_ok = None
    if answer.claim is not None and stable:
        claim_ok = abs(answer.claim - achieved) <= max(spec.claim_absolute, spec.claim_relative * abs(achieved))
    return ModelVerdict(stable, achieved, baseline, bool(stable and goal), claim_ok)


@dataclass(frozen=True)
class RigCase:
    """One design to try on one station's rig."""

    station: str
    item: str
    gains: Gains


def _commands(item: str, t: NDArray[np.float64], ramp_rate: float) -> list[NDArray[np.float64]]:
    """The tests a design faces on the rig: a step (holding still: stiction limit cycles), and for PI a ramp."""
    on = t >= 0.1
    step = np.where(on, STEP, 0.0)
    return [step] if item == "pd_design" else [step, np.where(on, ramp_rate * (t - 0.1), 0.0)]


def classify(r: NDArray[np.float64], y: NDArray[np.float64], u: NDArray[np.float64], *, threshold: float) -> RigVerdict:
    """ok, limit_cycle (tail oscillation RMS above ``threshold`` [in]) or unstable (diverged, or
    oscillating against the DAC limit)."""
    if not (np.all(np.isfinite(y)) and np.all(np.isfinite(u))):
        return "unstable"
    e = r - y
    if np.max(np.abs(e)) > 5.0 * np.max(np.abs(r)) + 1.0:
        return "unstable"
    n0 = int(0.6 * e.size)
    tail, k = e[n0:], np.arange(e.size - n0, dtype=float)
    resid = tail - np.polyval(np.polyfit(k, tail, 1), k)
    if np.std(resid) <= threshold:
        return "ok"
    return "unstable" if np.mean(np.abs(u[n0:]) >= 0.999 * DAC_LIMIT) > 0.05 else "limit_cycle"


def _station_rig(station: str) -> tuple[RigParams, EffectSet] | None:
    """The station's true parameters and effects, without sensor noise: random noise would make a
    design's verdict depend on the other designs simulated in its batch. Read once per version of
    the station's file (a web server checks many designs of one station)."""
    try:
        stat = station_file(station).stat()
    except OSError:
        return None
    return _read_station_rig(station, stat.st_mtime_ns, stat.st_size)


@lru_cache(maxsize=64)
def _read_station_rig(station: str, mtime_ns: int, size: int) -> tuple[RigParams, EffectSet] | None:
    """:func:`_station_rig` for one version (modification time [ns], size [bytes]) of the file."""
    try:
        s = load_station(station)
        effects = station_effects(s)
        return s.params(), (effects.without("sensor_noise") if "sensor_noise" in effects else effects)
    except GraderError:
        return None


def rig_verdicts(cases: Iterable[RigCase], *, threshold: float, ramp_rate: float = 1.0) -> dict[RigCase, RigVerdict | None]:
    """Verdicts for many designs, batched per station and design kind (None: no rig for the station)."""
    out: dict[RigCase, RigVerdict | None] = {}
    todo = sorted(set(cases), key=lambda c: (c.station, c.item, c.gains.Kp, c.gains.Ki, c.gains.Kd))
    for station in sorted({c.station for c in todo}):
        rig = _station_rig(station)
        for item in ("pd_design", "pi_design"):
            group = [c for c in todo if c.station == station and c.item == item]
            for start in range(0, len(group), RIG_BATCH):
                out.update(_run(group[start:start + RIG_BATCH], rig, threshold, ramp_rate))
    return out


@lru_cache(maxsize=1024)
def rig_verdict(case: RigCase, *, threshold: float) -> RigVerdict | None:
    """One design's verdict (cached per process; batches use :func:`rig_verdicts`)."""
    return rig_verdicts([case], threshold=threshold).get(case)


def _run(group: list[RigCase], rig: tuple[RigParams, EffectSet] | None, threshold: float,
         ramp_rate: float) -> dict[RigCase, RigVerdict | None]:
    from grader.model.rig import simulate_rig_batch  # the compiled engine: only when a design is simulated

    if not group:
        return {}
    if rig is None:
        return dict.fromkeys(group)
    p, effects = rig
    t = np.arange(0.0, RIG_SECONDS, p.sample_time)
    controllers = [Controller(c.gains.Kp, c.gains.Ki, c.gains.Kd) for c in group]
    worst: dict[RigCase, RigVerdict] = dict.fromkeys(group, "ok")
    rank = {"ok": 0, "limit_cycle": 1, "unstable": 2}
    for r in _commands(group[0].item, t, ramp_rate):
        try:
            with np.errstate(all="ignore"):
                Y, U = simulate_rig_batch(p, controllers, t, r, effects, rng=np.random.default_rng(0))
        except GraderError:
            return dict.fromkeys(group)
        for case, y, u in zip(group, Y, U):
            v = classify(r, y, u, threshold=threshold)
            worst[case] = max(worst[case], v, key=rank.__getitem__)
    return dict(worst)
