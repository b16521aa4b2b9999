"""Predictions from an identified model, as the lab asks for them.

Overshoot-based gains use the sampled loop's step response (the rig is digital):
``Kp_no_overshoot`` is the largest P gain whose overshoot stays below
:data:`NO_OVERSHOOT` (0.5 %, the smallest a student can read off a plot), and
``Kp_25_overshoot`` the gain giving 25 % overshoot.
"""

from __future__ import annotations

from collections.abc import Mapping

import control as ct
import numpy as np
from scipy.optimize import brentq

from grader.datasets import Run
from grader.errors import IdentificationError
from grader.identify.critical import match_sampled_poles
from grader.identify.estimate import Estimate, propagate
from grader.identify.pipeline import Identification
from grader.model.linear import ramp_error
from grader.model.params import Controller, RigParams
from grader.model.sampled import discrete_critical_gain, discrete_loop

NO_OVERSHOOT = 0.005


def overshoot(p: RigParams, kp: float, *, duration: float = 4.0) -> float:
    """Fractional step overshoot of the sampled P loop at gain ``kp``."""
    y_r, _ = discrete_loop(p, Controller(Kp=kp))
    n = int(duration / p.sample_time)
    y = ct.step_response(y_r, T=np.arange(n) * p.sample_time).outputs
    return float(max(y.max() - 1.0, 0.0))


def gain_for_overshoot(p: RigParams, target: float, *, k_crit: float | None = None) -> float:
    """P gain whose sampled step response overshoots by ``target`` (fraction)."""
    k_crit = k_crit or discrete_critical_gain(p)
    hi = 0.995 * k_crit
    if overshoot(p, hi) < target:
        raise IdentificationError(f"{100 * target:.1f} % overshoot is not reachable below the critical gain")
    return float(brentq(lambda k: overshoot(p, k) - target, 1e-3 * k_crit, hi, xtol=1e-6 * k_crit))


def gain_no_overshoot(p: RigParams, *, k_crit: float | None = None) -> float:
    """Largest P gain with overshoot below :data:`NO_OVERSHOOT`."""
    return gain_for_overshoot(p, NO_OVERSHOOT, k_crit=k_crit)


def critical_gain_sampled(p: RigParams) -> float:
    """Critical P gain of the sampled loop."""
    return discrete_critical_gain(p)


def _ramp_rate(run: Run) -> float:
    """Slope [in/s] of the command over the second half of the run."""
    half = run.t >= run.t[0] + 0.5 * (run.t[-1] - run.t[0])
    return float(np.polyfit(run.t[half], run.r[half], 1)[0])


def predictions(ident: Identification) -> dict[str, Estimate]:
    """Model-refined β/Vt and Kce, the predicted gains, ramp error and characteristic polynomial."""
    ds = ident.dataset
    est = ident.estimates
    base = ident.params
    p_ramps = [r for r in ds.runs_of("ramp") if r.controller.Ki == 0 and r.controller.Kd == 0]
    names = ("omega_crit", "growth_rate", "Kq", "Kpot")
    x = {k: est[k].value for k in names}
    se = {k: est[k].se for k in names}
    if ds.manifest.feedback == "inches":
        se["Kpot"] = 0.0

    def evaluate(v: Mapping[str, float]) -> list[float]:
        p = match_sampled_poles(base.with_(Kq=v["Kq"], Kpot=v["Kpot"]), kp=ident.kp_run, sigma=v["growth_rate"], omega=v["omega_crit"])
        kc = critical_gain_sampled(p)
        out = [p.beta_over_Vt, p.Kce, kc, gain_no_overshoot(p, k_crit=kc), gain_for_overshoot(p, 0.25, k_crit=kc)]
        if p_ramps:
            out.append(ramp_error(p, p_ramps[0].controller.Kp, _ramp_rate(p_ramps[0])))
        return out

    values, ses = propagate(evaluate, x, se, central=False)
    gain_unit = "dimensionless" if ds.manifest.feedback == "volts" else "V/in"
    inputs = {"Kp_run": ident.kp_run, "sample_time [s]": base.sample_time}
    sampled = "sampled loop (ZOH at the manifest's sample time)"
    out = {
        "beta_over_Vt_model": Estimate(values[0], "psi/in**3", ses[0], "sampled-loop poles placed at the measured σ ± jω", inputs),
        "Kce_model": Estimate(values[1], "in**3/s/psi", ses[1], "sampled-loop poles placed at the measured σ ± jω", inputs),
        "Kp_crit_model": Estimate(values[2], gain_unit, ses[2], f"critical gain of the identified {sampled}", inputs),
        "Kp_no_overshoot": Estimate(values[3], gain_unit, ses[3], f"largest gain with < {100 * NO_OVERSHOOT:g} % overshoot, {sampled}", inputs),
        "Kp_25_overshoot": Estimate(values[4], gain_unit, ses[4], f"gain giving 25 % overshoot, {sampled}", inputs),
    }
    if p_ramps:
        run = p_ramps[0]
        out["ramp_ess_P"] = Estimate(values[5], "in", ses[5], "ramp rate / Kv of the identified model",
                                     {"run": run.name, "Kp": run.controller.Kp, "ramp rate [in/s]": _ramp_rate(run)})
    return out

