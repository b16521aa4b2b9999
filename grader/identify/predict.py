"""Predictions from an identified model, as the lab asks for them.

Overshoot-based gains use the sampled loop's step response (the rig is digital, see
:mod:`grader.model.zloop`): ``Kp_no_overshoot`` is the largest P gain whose overshoot
stays below :data:`~grader.model.zloop.NO_OVERSHOOT` (0.5 %), and ``Kp_25_overshoot``
the gain giving 25 % overshoot. A prediction the identified rig cannot have (a lightly
damped loop that goes unstable before it overshoots 25 %, a loop stable at every gain,
a ramp run at an unstable gain, a missing P ramp run) is a ``not_reachable`` Estimate
with a reason, never an error.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from grader.datasets import Run
from grader.identify.critical import match_sampled_poles
from grader.identify.estimate import Estimate, not_identifiable, not_reachable, propagate
from grader.identify.pipeline import Identification
from grader.model import zloop
from grader.model.linear import ramp_error
from grader.model.params import Controller, RigParams

NAN = float("nan")
#: below its critical gain, the overshoot search stops this close to it (as zloop does)
NEAR_CRITICAL = 0.995


#: A P ramp whose command moves less than this [in] over the run's second half has no ramp error to predict.
LEAST_RAMP = 1e-6


def _ramp_rate(run: Run) -> float:
    """Slope [in/s] of the command over the second half of the run."""
    half = run.t >= run.t[0] + 0.5 * (run.t[-1] - run.t[0])
    return float(np.polyfit(run.t[half], run.r[half], 1)[0])


def _or_nan(value: float | None) -> float:
    return NAN if value is None or not np.isfinite(value) else float(value)


def overshoot_reason(p: RigParams, target: float) -> str:
    """Why no P gain of the identified loop gives ``target`` overshoot (fraction)."""
    kc = zloop.critical_gain(p)
    if not np.isfinite(kc):
        return "the identified loop is stable at every P gain and never overshoots"
    peak = zloop.overshoot(p, Controller(Kp=NEAR_CRITICAL * kc))
    if peak < target:
        return (f"the identified loop peaks at {100 * peak:.0f} % overshoot below its critical gain {kc:.3g}, "
                f"so no P gain gives {100 * target:g} % overshoot")
    return f"the identified loop overshoots by more than {100 * target:g} % even at the smallest gains"


def _ramp_estimate(p: RigParams, run: Run | None, value: float, se: float) -> Estimate:
    method = "ramp rate / Kv of the identified model"
    if run is None:
        return not_reachable("in", method, "the dataset has no P-only ramp run to predict")
    rate = _ramp_rate(run)
    inputs = {"run": run.name, "Kp": run.controller.Kp, "ramp rate [in/s]": rate}
    if abs(rate) * 0.5 * (run.t[-1] - run.t[0]) < LEAST_RAMP:
        return not_identifiable("in", method, f"the P ramp run {run.name}'s command does not ramp over its second half "
                                              f"(slope {rate:.3g} in/s): there is no steady ramp error to predict")
    if not np.isfinite(value):
        return not_reachable("in", method, f"the P ramp run's gain {run.controller.Kp:g} is at or above the identified "
                                           f"critical gain {zloop.critical_gain(p):.3g}: the loop has no steady ramp error", inputs)
    return Estimate(value, "in", se, method, inputs)


def _not_identifiable(ident: Identification) -> dict[str, Estimate]:
    """Every prediction ``not_identifiable``, for a dataset whose instability run gives no model."""
    gain_unit = "dimensionless" if ident.dataset.manifest.feedback == "volts" else "V/in"
    units = {"beta_over_Vt_model": "psi/in**3", "Kce_model": "in**3/s/psi", "Kp_crit_model": gain_unit,
             "Kp_no_overshoot": gain_unit, "Kp_25_overshoot": gain_unit, "ramp_ess_P": "in"}
    reason = f"needs β/Vt and Kce, which the data do not give: {ident.estimates['Kce'].reason}"
    return {name: not_identifiable(unit, "from the identified model", reason) for name, unit in units.items()}


def predictions(ident: Identification) -> dict[str, Estimate]:
    """Model-refined β/Vt and Kce, the predicted gains, ramp error and characteristic polynomial
    (all ``not_identifiable`` when the dataset gives no model)."""
    ds = ident.dataset
    est = ident.estimates
    base = ident.params
    if base is None:
        return _not_identifiable(ident)
    p_ramps = [r for r in ds.runs_of("ramp") if r.controller.Ki == 0 and r.controller.Kd == 0]
    ramp = p_ramps[0] if p_ramps else None
    names = ("omega_crit", "growth_rate", "Kq", "Kpot")
    x = {k: est[k].value for k in names}
    se = {k: est[k].se for k in names}
    if ds.manifest.feedback == "inches":
        se["Kpot"] = 0.0
    x["B"], se["B"] = ident.match_B, est["B"].se if ident.match_B > 0 else 0.0  # the viscous B the poles are placed with

    def evaluate(v: Mapping[str, float]) -> list[float]:
        p = match_sampled_poles(base.with_(Kq=v["Kq"], Kpot=v["Kpot"], B=v["B"]), kp=ident.kp_run,
                                sigma=v["growth_rate"], omega=v["omega_crit"])
        kc = zloop.critical_gain(p)
        out = [p.beta_over_Vt, p.Kce, _or_nan(kc), _or_nan(zloop.gain_no_overshoot(p)), _or_nan(zloop.gain_for_overshoot(p, 0.25))]
        stable = ramp is not None and ramp.controller.Kp < kc
        out.append(ramp_error(p, ramp.controller.Kp, _ramp_rate(ramp)) if stable and ramp is not None else NAN)
        return out

    values, ses = propagate(evaluate, x, se)
    gain_unit = "dimensionless" if ds.manifest.feedback == "volts" else "V/in"
    inputs = {"Kp_run": ident.kp_run, "sample_time [s]": base.sample_time}
    sampled = "sampled loop (ZOH at the manifest's sample time)"
    methods = {
        "Kp_crit_model": f"critical gain of the identified {sampled}",
        "Kp_no_overshoot": f"largest gain with < {100 * zloop.NO_OVERSHOOT:g} % overshoot, {sampled}",
        "Kp_25_overshoot": f"gain giving 25 % overshoot, {sampled}",
    }
    reasons = {"Kp_crit_model": lambda: overshoot_reason(base, np.inf),
               "Kp_no_overshoot": lambda: overshoot_reason(base, zloop.NO_OVERSHOOT),
               "Kp_25_overshoot": lambda: overshoot_reason(base, 0.25)}
    out = {
        "beta_over_Vt_model": Estimate(values[0], "psi/in**3", ses[0], "sampled-loop poles placed at the measured σ ± jω", inputs),
        "Kce_model": Estimate(values[1], "in**3/s/psi", ses[1], "sampled-loop poles placed at the measured σ ± jω", inputs),
    }
    for k, (name, method) in enumerate(methods.items(), start=2):
        out[name] = (Estimate(values[k], gain_unit, ses[k], method, inputs) if np.isfinite(values[k])
                     else not_reachable(gain_unit, method, reasons[name](), inputs))
    out["ramp_ess_P"] = _ramp_estimate(base, ramp, values[5], ses[5])
    return out
