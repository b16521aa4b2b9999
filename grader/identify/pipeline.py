"""The students' identification procedure on one lab dataset, done right.

:func:`identify` turns a :class:`~grader.datasets.Dataset` into Estimates of Kpot, Kq,
leakage, B, Fc, ω and Kp at the limit of stability, β/Vt and Kce (the students'
coefficient matching), plus the refined model :class:`RigParams` whose sampled loop
reproduces the measured oscillation. :func:`predict` derives the gains and errors the
lab asks students to predict, with intervals propagated from the measurements.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np

from grader.datasets import Dataset, Run
from grader.errors import IdentificationError
from grader.identify.critical import coefficient_match, match_sampled_poles
from grader.identify.estimate import Estimate, not_identifiable, propagate
from grader.identify.flow import FlowGainFit
from grader.identify.friction import FrictionFit
from grader.identify.oscillation import OscillationFit
from grader.identify.pot import PotCalibration
from grader.model.linear import plant_coeffs
from grader.model import zloop
from grader.model.params import Controller, RigParams
from grader.model.rig_setup import DAC_LIMIT
from grader.precision import round_sig


@dataclass(frozen=True)
class Identification:
    """Identified values (``estimates``) and the refined linear model (``params``)."""

    estimates: Mapping[str, Estimate]
    #: None (and the instability items ``not_identifiable``) when the instability run shows no
    #: sustained critical oscillation of the loop
    params: RigParams | None
    students_params: RigParams | None
    kp_run: float
    dataset: Dataset
    #: damping [lbf·s/in] with which the model's poles are placed at the instability run's oscillation
    #: (the viscous B: Coulomb friction's effect is taken out of the fitted growth rate)
    match_B: float = 0.0


def command_start(run: Run) -> float:
    """Time [s] at which the command first changes (the step or ramp starts)."""
    moved = np.flatnonzero(np.abs(run.r - run.r[0]) > 1e-12)
    return float(run.t[moved[0]]) if moved.size else float(run.t[0])


def _require(dataset: Dataset, what: str) -> None:
    if getattr(dataset, what) is None:
        raise IdentificationError(f"{dataset.root.name}: the manifest names no {what} file, needed to identify the model")


def _instability_run(dataset: Dataset) -> Run:
    runs = dataset.runs_of("instability")
    if not runs:
        raise IdentificationError(f"{dataset.root.name}: no run of kind 'instability'; β/Vt and Kce need one")
    return runs[0]


def _coefficient_model(g: Mapping[str, float], feedback: str, kp: float, B: float, omega: float, Kq: float,
                       Kpot: float) -> RigParams:
    """The students' model: β/Vt and Kce by coefficient matching at ``omega`` [rad/s] and gain ``kp``."""
    bv, kce = coefficient_match(omega=omega, kp_crit=kp, A=g["A"], M=g["M"], Kamp=g["Kamp"], Kq=Kq,
                                k_fb=Kpot if feedback == "volts" else 1.0, B=B)
    return RigParams(A=g["A"], M=g["M"], Kamp=g["Kamp"], Kq=Kq, Kpot=Kpot, beta_over_Vt=bv, Kce=kce, B=B,
                     sample_time=g["sample_time"], feedback=feedback, supply_pressure=g["supply_pressure"], i_max=g["i_max"])


#: Significant digits of Coulomb friction's decrement (see :func:`friction_decrement`).
DECREMENT_DIGITS = 4


def friction_decrement(p: RigParams, kp: float, Fc: float, omega: float) -> float:
    """Rate [in/s] at which Coulomb friction ``Fc`` [lbf] slows the growth of the P loop's oscillation
    amplitude at ``omega`` [rad/s]: its describing function is a damping 4·Fc/(π·a·ω) at amplitude a,
    which lowers the growth rate by ∂σ/∂B times it, so da/dt = σ·a − c with c = −∂σ/∂B·4·Fc/(π·ω)
    (∂σ/∂B of the sampled loop ``p`` at ``kp``, by a second-order one-sided difference).

    The same bytes on any CPU: the loop's roots carry last-digit differences between BLAS kernels, which a
    difference quotient magnifies (to 3e-7 of c with a step of 0.1 % of M·ω, enough to move the growth rate's
    6th digit). A step of 5 % of M·ω (σ(B) is smooth on the scale of M·ω) and c rounded to
    :data:`DECREMENT_DIGITS` significant digits, far finer than the describing function's own accuracy, remove it."""
    if Fc <= 0 or omega <= 0:
        return 0.0

    def sigma(B: float) -> float:
        s = np.log(np.roots(zloop.closed_loop(p.with_(B=B), Controller(Kp=kp))[1]).astype(complex)) / p.sample_time
        return float(s[np.argmin(np.abs(s - 1j * omega))].real)

    h = 0.05 * max(p.M * omega, 1e-6)
    slope = (4.0 * sigma(p.B + h) - sigma(p.B + 2.0 * h) - 3.0 * sigma(p.B)) / (2.0 * h)
    return round_sig(max(-slope, 0.0) * 4.0 * Fc / (np.pi * omega), DECREMENT_DIGITS)


def saturation_amplitude(g: Mapping[str, float], kp: float, k_fb: float) -> float:
    """Position amplitude [in] at which the P controller's output reaches the DAC limit or the
    amplifier's ``i_max``: the oscillation stops growing freely there."""
    return min(DAC_LIMIT, g["i_max"] / g["Kamp"]) / (kp * k_fb)


#: the items the instability run gives (unit, what): not identifiable without its critical oscillation
INSTABILITY_ITEMS = {"omega_crit": "rad/s", "growth_rate": "1/s", "Kp_crit": None, "beta_over_Vt": "psi/in**3",
                     "Kce": "in**3/s/psi", "char_poly_a2": "1/s", "char_poly_a1": "1/s**2", "char_poly_a0_per_Kp": None}


class _NeedsKq(IdentificationError):
    """The instability run oscillates, but no model matches it without Kq: ``estimates`` holds what the run gives
    alone (ω_crit, the growth rate, Kp_crit)."""

    def __init__(self, reason: str, estimates: Mapping[str, Estimate]) -> None:
        super().__init__(reason)
        self.estimates = dict(estimates)


def _kp_crit(kp: float, volts: bool, run: Run) -> Estimate:
    return Estimate(kp, "dimensionless" if volts else "V/in", 0.0, "gain of the instability run (manifest)",
                    {"run": run.name})


def _friction(dataset: Dataset) -> tuple[dict[str, Estimate], float]:
    """B [lbf·s/in] and Fc [lbf] from the friction test, and the model's B (0 where B's interval holds 0, as the
    lab concludes). Without a friction test (the manifest names no friction file) both are ``not_identifiable``,
    and the model has no friction: B = 0 and no decrement of the oscillation's growth."""
    if dataset.friction is None:
        reason = "the dataset has no friction test (the manifest names no friction file); the model takes B = 0"
        return {"B": not_identifiable("lbf*s/in", "OLS slope of force on speed", reason),
                "Fc": not_identifiable("lbf", "OLS of force on sign(speed) and speed", reason)}, 0.0
    fric = FrictionFit().fit(dataset.friction["speed"], dataset.friction["force"])
    return {"B": fric.B_, "Fc": fric.Fc_}, 0.0 if fric.B_is_zero_ else fric.B_.value


def identify(dataset: Dataset) -> Identification:
    """Run the identification procedure on ``dataset``."""
    for what in ("calibration", "flow_test"):
        _require(dataset, what)
    g = dataset.given
    pot = PotCalibration().fit(dataset.calibration["position"], dataset.calibration["voltage"])
    flow = FlowGainFit(Kamp=g["Kamp"]).fit(dataset.flow_test["input"], dataset.flow_test["flow"])
    friction, B_model = _friction(dataset)
    static = {"Kpot": pot.Kpot_, "Kq": flow.Kq_, "leakage": flow.leakage_, **friction}
    run = _instability_run(dataset)
    try:
        est, model, students = _from_oscillation(dataset, run, static, B_model)
    except IdentificationError as exc:
        volts = dataset.manifest.feedback == "volts"
        units = {**INSTABILITY_ITEMS, "Kp_crit": "dimensionless" if volts else "V/in",
                 "char_poly_a0_per_Kp": "1/s**3" if volts else "in/V/s**3"}
        reason = str(exc).removeprefix("instability run: ")
        est = {name: not_identifiable(unit, f"from the instability run {run.name}", reason) for name, unit in units.items()}
        est.update(exc.estimates if isinstance(exc, _NeedsKq) else {})
        model = students = None
    return Identification(estimates={**static, **est}, params=model, students_params=students,
                          kp_run=run.controller.Kp, dataset=dataset, match_B=B_model)


def _from_oscillation(dataset: Dataset, run: Run, static: Mapping[str, Estimate],
                      B_model: float) -> tuple[dict[str, Estimate], RigParams, RigParams]:
    """The instability run's estimates, the refined model and the students' model (IdentificationError
    when the run shows no sustained oscillation of the loop or no model matches it)."""
    g, fb = dataset.given, dataset.manifest.feedback
    kp, volts = run.controller.Kp, fb == "volts"
    Kq, Kpot = static["Kq"], static["Kpot"]
    a_sat = saturation_amplitude(g, kp, Kpot.value if volts else 1.0)
    first = OscillationFit(a_sat).fit(run.t, run.y, start=command_start(run))
    if not first.usable_:
        raise IdentificationError(f"{first.why_not_}; raise Kp until the oscillation grows")
    if Kq.status != "ok":  # the oscillation is read; friction's decrement and the matching need the model's Kq
        raw = "as read, without Coulomb friction's decrement (it needs Kq, which the flow test does not give)"
        raise _NeedsKq(f"needs Kq, which the flow test does not give: {Kq.reason}",
                       {"omega_crit": first.omega_, "growth_rate": replace(first.sigma_, note=raw),
                        "Kp_crit": _kp_crit(kp, volts, run)})
    rough = _coefficient_model(g, fb, kp, B_model, first.omega_.value, Kq.value, Kpot.value)
    fc = static["Fc"].value if static["Fc"].status == "ok" else 0.0
    c = friction_decrement(rough, kp, fc, first.omega_.value)
    osc = OscillationFit(a_sat).fit(run.t, run.y, start=command_start(run), decrement=c, guess=first) if c > 0 else first
    x = {"omega": osc.omega_.value, "Kq": Kq.value, "Kpot": Kpot.value}
    se = {"omega": osc.omega_.se, "Kq": Kq.se, "Kpot": Kpot.se if volts else 0.0}

    def match(v: Mapping[str, float]) -> tuple[float, ...]:
        p = _coefficient_model(g, fb, kp, B_model, v["omega"], v["Kq"], v["Kpot"])
        a2, a1, b0 = plant_coeffs(p)
        return p.beta_over_Vt, p.Kce, a2, a1, g["Kamp"] * (v["Kpot"] if volts else 1.0) * b0

    (bv, kce, a2, a1, a0k), ses = propagate(match, x, se)
    inputs = {"omega_crit [rad/s]": x["omega"], "Kp_crit": kp, "Kq [in^3/s/mA]": x["Kq"], "Kpot [V/in]": x["Kpot"],
              "B [lbf*s/in]": B_model, "A [in^2]": g["A"], "M [lbf*s^2/in]": g["M"], "Kamp [mA/V]": g["Kamp"]}
    matching = "coefficient matching at the limit of stability"
    students = _coefficient_model(g, fb, kp, B_model, x["omega"], x["Kq"], x["Kpot"])
    model = match_sampled_poles(students, kp=kp, sigma=osc.sigma_.value, omega=osc.omega_.value)
    est = {
        "omega_crit": osc.omega_,
        "growth_rate": osc.sigma_,
        "Kp_crit": _kp_crit(kp, volts, run),
        "beta_over_Vt": Estimate(bv, "psi/in**3", ses[0], f"{matching} (ζ = 0)", inputs),
        "Kce": Estimate(kce, "in**3/s/psi", ses[1], f"{matching} (ζ = 0)", inputs),
        "char_poly_a2": Estimate(a2, "1/s", ses[2], f"s² coefficient, B/M + 4β/Vt·Kce, after {matching}", inputs),
        "char_poly_a1": Estimate(a1, "1/s**2", ses[3], f"s coefficient, 4β/Vt·(A² + B·Kce)/M, after {matching}", inputs),
        "char_poly_a0_per_Kp": Estimate(a0k, "1/s**3" if volts else "in/V/s**3", ses[4],
                                        f"constant term per unit Kp, Kamp·{'Kpot·' if volts else ''}4β/Vt·Kq·A/M", inputs),
    }
    return est, model, students
