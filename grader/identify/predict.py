"""Predictions from an identified model, as the lab asks for them.

Overshoot-based gains use the sampled loop's step response (the rig is digital, see
:mod:`grader.model.zloop`): ``Kp_no_overshoot`` is the largest P gain whose overshoot
stays below :data:`~grader.model.zloop.NO_OVERSHOOT` (0.5 %), and ``Kp_25_overshoot``
the gain giving 25 % overshoot.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from grader.datasets import Run
from grader.errors import IdentificationError
from grader.identify.critical import match_sampled_poles
from grader.identify.estimate import Estimate, propagate
from grader.identify.pipeline import Identification
from grader.model import zloop
from grader.model.linear import ramp_error


def _required(value: float | None, what: str) -> float:
    if value is None:
        raise IdentificationError(f"the identified model never reaches {what} below its critical gain")
    return value


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
        out = [p.beta_over_Vt, p.Kce, zloop.critical_gain(p),
               _required(zloop.gain_no_overshoot(p), "a step response without overshoot"),
               _required(zloop.gain_for_overshoot(p, 0.25), "25 % overshoot")]
        if p_ramps:
            out.append(ramp_error(p, p_ramps[0].controller.Kp, _ramp_rate(p_ramps[0])))
        return out

    values, ses = propagate(evaluate, x, se)
    gain_unit = "dimensionless" if ds.manifest.feedback == "volts" else "V/in"
    inputs = {"Kp_run": ident.kp_run, "sample_time [s]": base.sample_time}
    sampled = "sampled loop (ZOH at the manifest's sample time)"
    out = {
        "beta_over_Vt_model": Estimate(values[0], "psi/in**3", ses[0], "sampled-loop poles placed at the measured σ ± jω", inputs),
        "Kce_model": Estimate(values[1], "in**3/s/psi", ses[1], "sampled-loop poles placed at the measured σ ± jω", inputs),
        "Kp_crit_model": Estimate(values[2], gain_unit, ses[2], f"critical gain of the identified {sampled}", inputs),
        "Kp_no_overshoot": Estimate(values[3], gain_unit, ses[3], f"largest gain with < {100 * zloop.NO_OVERSHOOT:g} % overshoot, {sampled}", inputs),
        "Kp_25_overshoot": Estimate(values[4], gain_unit, ses[4], f"gain giving 25 % overshoot, {sampled}", inputs),
    }
    if p_ramps:
        run = p_ramps[0]
        out["ramp_ess_P"] = Estimate(values[5], "in", ses[5], "ramp rate / Kv of the identified model",
                                     {"run": run.name, "Kp": run.controller.Kp, "ramp rate [in/s]": _ramp_rate(run)})
    return out

