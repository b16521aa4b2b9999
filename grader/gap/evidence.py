"""Evidence beside the closed-loop runs that names an effect: the friction test and a quantising ADC.

* **Friction test** (force against speed, :class:`grader.identify.FrictionFit`): its slope is the
  viscous friction B and its intercept the Coulomb level Fc, each with a 95 % interval from the
  regression. Viscous friction acts in the closed loop almost exactly as a larger Kce, so the
  runs alone cannot name it; the friction test can. It is named when B's interval excludes 0
  and B reaches :data:`VISIBLE` of its realistic range's top. The Coulomb level breaks a tie:
  when the runs cannot tell Coulomb friction from the verdict (a deadband or backlash looks alike
  in closed loop), a friction test whose Fc is clearly above 0 and inside the fitted Coulomb
  candidate's interval makes Coulomb friction the verdict.
* **Flow test against the runs' loop gain** (only without a friction test). With the loop gain
  free, the runs absorb B into Kce and a smaller Kq (the closed loop has three coefficients,
  :func:`grader.model.linear.plant_coeffs`, and B enters two of them). The verdict's fitted linear
  model (``none``'s, or the one effect's the runs name) then has a Kq below the flow test's; a deficit
  of :data:`DEFICIT_Z` standard errors or more (the flow test's, the runs' and, with volts feedback,
  the calibration's Kpot's combined) names viscous friction, as the verdict or beside the runs' effect,
  with the B that gives the runs' closed loop at the flow test's Kq (and its interval from the
  deficit's, reaching a second B that gives the same loop where that is a realistic rig:
  :func:`viscous_b`). A deficit that no B explains names nothing.
* **ADC** (:mod:`grader.gap.quantization`): named when its step matters.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from grader.datasets import Dataset
from grader.errors import IdentificationError
from grader.gap import build
from grader.gap.candidates import NONE
from grader.gap.quantization import QUANTIZATION, Quantization
from grader.gap.schema import TIE_TO_COULOMB, Candidate, LoopGainInfo, Value, Verdict
from grader.gap.separating import separating_test, would
from grader.gap.verdict import Ranking
from grader.identify.estimate import Z95, Estimate
from grader.model.effects import EFFECTS
from grader.model.linear import plant_coeffs
from grader.model.params import RigParams

VISIBLE = 0.1  # of the realistic range's top
#: The runs' Kq this many standard errors below the flow test's names viscous friction, as the verdict or beside an
#: effect the runs name. On 160 benchmark rigs with no effect (seeds 600 and 700) the deficit's z had mean 0.09 and
#: spread 1.03: it is a unit normal, so 2.5 (one-sided) names viscous friction on 0.6 % of rigs without it, and
#: leaves the rest of the 3 % false-positive budget to the runs. Beside an effect the runs name, over 236 rigs
#: (seeds 300 and 500) the z spread 1.3 and never passed 2.32. With each standard error taken from its t interval's
#: width (:func:`_rel_se`, :func:`_log_se`), on 175 rigs with no effect (seed 900's 150, seed 300's 25) z had mean
#: −0.05 and spread 1.01 (1.07 with the standard errors themselves, the calibration's Kpot's z alone spreading 1.21),
#: and passed 2.5 on 2 of them (1.1 %, Wilson 95 % 0.3–4.1 %): matching the intervals' widths fixes the spread, while
#: the t tails beyond 2.5 stay a little heavier than a normal's (0.6 %).
DEFICIT_Z = 2.5
#: Realistic rigs (docs/reference/rig-space.md): Kce [in³/s/psi] at least this, B [lbf·s/in] at most the top of
#: viscous friction's realistic range.
KCE_REALISTIC = 1e-4
B_REALISTIC = EFFECTS["viscous_friction"].params[0].typical[1]


@dataclass(frozen=True)
class Friction:
    """The friction test's Coulomb level Fc [lbf] and viscous B [lbf·s/in], as (value, lo, hi)."""

    Fc: tuple[float, float, float]
    B: tuple[float, float, float]

    def shows(self, effect: str) -> bool:
        """Whether the test shows ``effect`` (interval above 0, value visible)."""
        value, lo, _ = self.Fc if effect == "coulomb_friction" else self.B
        return lo > 0 and value >= VISIBLE * EFFECTS[effect].params[0].typical[1]

    def values(self) -> dict[str, dict[str, Value]]:
        """Both estimates as diagnosis.json values."""
        return {"coulomb_friction": {"Fc": build.value(self.Fc[0], "lbf", self.Fc[1:])},
                "viscous_friction": {"B": build.value(self.B[0], "lbf*s/in", self.B[1:])}}


def friction(ds: Dataset) -> Friction | None:
    """The friction test's estimates, if the dataset has a usable one."""
    if ds.friction is None:
        return None
    from grader.identify.friction import FrictionFit

    try:
        fit = FrictionFit().fit(ds.friction["speed"], ds.friction["force"])
    except (IdentificationError, ValueError, ArithmeticError):
        return None
    return Friction((fit.Fc_.value, *fit.Fc_.interval), (fit.B_.value, *fit.B_.interval))


def _add(verdict: Verdict, name: str, text: str) -> Verdict:
    """``name`` as the verdict (if it is none) or as its second effect (if that is free), else told in the
    explanation as a third effect, not named (a verdict names two at most). A verdict named this way has no margin
    over the runs' runner-up (the runs alone rank it with ``none``)."""
    if verdict.effect == NONE:
        return verdict.model_copy(update={"effect": name, "shares": {name: 1.0}, "explanation": text, "margin": 0.0,
                                          "runner_up": NONE, "indistinguishable_from": [], "separating_test": None,
                                          "not_ruled_out": []})
    if verdict.second_effect is None:  # no share of the held-out shrink: it is not fitted to the runs
        return verdict.model_copy(update={"second_effect": name, "shares": {**verdict.shares, name: 0.0},
                                          "explanation": f"{verdict.explanation}; and {text}"})
    return verdict.model_copy(update={"not_named": [*verdict.not_named, name], "explanation": (
        f"{verdict.explanation}; beside these two, {text} (a third effect, {name}, not named: a verdict names two at "
        "most)")})


def coulomb_tie(rk: Ranking, names: list[str], cands: list[Candidate], fr: Friction | None) -> tuple[Ranking, str]:
    """The ranking with Coulomb friction as the verdict when tied with it and the friction test supports it
    (module docstring), and why ('' if unchanged); ``cands`` are the built candidates in ``names``' order."""
    name = "coulomb_friction"
    if fr is None or name not in names or not fr.shows(name):
        return rk, ""
    c = names.index(name)
    if names[rk.verdict] in (NONE, name) or c not in rk.ties:
        return rk, ""
    lo, hi = cands[c].params["Fc"].interval or (cands[c].params["Fc"].value,) * 2
    if not lo <= fr.Fc[0] <= hi:
        return rk, ""
    old = rk.verdict
    ties = [old, *(i for i in rk.ties if i != c)]
    order = [c, old, *(i for i in rk.order if i not in (c, old))]
    why = (f"the friction test shows Fc = {fr.Fc[0]:.3g} lbf, inside the fitted Coulomb level's interval, "
           f"{TIE_TO_COULOMB}")
    return replace(rk, order=order, verdict=c, runner_up=old, margin=0.0, ties=ties), why


def viscous(verdict: Verdict, fr: Friction | None) -> Verdict:
    """Viscous friction named from the friction test when it shows B (module docstring)."""
    if fr is None or not fr.shows("viscous_friction") or "viscous_friction" in (verdict.effect, verdict.second_effect):
        return verdict
    return _add(verdict, "viscous_friction",
                f"the friction test shows viscous friction B = {fr.B[0]:.3g} lbf·s/in (95 % interval "
                f"{fr.B[1]:.3g} to {fr.B[2]:.3g}); in the closed loop it acts as a larger Kce")


def beside_runs(verdict: Verdict, fr: Friction | None, lg: LoopGainInfo | None,
                quant: Quantization | None) -> Verdict:
    """The runs' ``verdict`` with what the evidence beside them names, the direct readings first: the friction test
    (:func:`viscous`), the ADC seen in the readings (:func:`quantized`), then the loop gain's deficit
    (:func:`viscous_from_loop_gain`), and a ``none`` verdict's viscous friction not ruled out
    (:func:`viscous_unexcluded`)."""
    verdict = quantized(viscous(verdict, fr), quant)
    return viscous_unexcluded(viscous_from_loop_gain(verdict, lg), fr, lg)


def quantized(verdict: Verdict, quant: Quantization | None) -> Verdict:
    """sensor_quantization named when the ADC matters."""
    if quant is None or not quant.matters:
        return verdict
    return _add(verdict, "sensor_quantization", quant.text())


def _roots(runs: RigParams, kq: float) -> tuple[float, tuple[float, float], bool]:
    """The viscous friction B [lbf·s/in] to add to ``runs`` so that, with Kq = ``kq`` and β/Vt, Kce re-fitted, its
    plant coefficients (:func:`~grader.model.linear.plant_coeffs`) are those of ``runs``; the other B that does so
    with the Kce [in³/s/psi] it implies; and whether they do so exactly. b0 fixes g = 4β/Vt, a2 then Kce, and a1
    leaves a quadratic in B, B² − a2·M·B + M·(a1·M − g·A²) = 0, whose smaller root is right while B/M is less of
    the damping than g·Kce, the larger where it is more. Beyond the largest deficit any B explains (no real root),
    both are the B that comes closest in the stiffness a1 (the other two exact), a2·M/2, not exact. Both less
    ``runs``' own B. In closed form: the same bytes on any CPU."""
    a2, a1, b0 = plant_coeffs(runs)
    g = b0 * runs.M / (kq * runs.A)
    disc = (a2 * runs.M) ** 2 - 4.0 * runs.M * (a1 * runs.M - g * runs.A**2)
    half = 0.5 * math.sqrt(max(disc, 0.0))
    small, large = 0.5 * a2 * runs.M - half, 0.5 * a2 * runs.M + half
    exact = bool(disc >= 0.0 and small >= runs.B)
    return max(small - runs.B, 0.0), (large - runs.B, (a2 - large / runs.M) / g), exact


def viscous_b(runs: RigParams, d: float, sigma: float) -> tuple[float, float, float, bool, float | None]:
    """B [lbf·s/in] behind a loop-gain deficit ``d`` = ln(flow test Kq / runs' Kq) of standard error ``sigma``:
    (B, lo, hi, whether a B within the deficit's 95 % interval explains it exactly, the deficit's larger root
    where the interval reaches up to it and it is a realistic rig, else None). B and the interval come from the
    smaller root. Where the mechanical damping B/M can exceed the hydraulic g·Kce, the larger root gives the
    same closed loop, and the data cannot choose: for a deficit clearly above 0, the interval then reaches up to
    the larger root of the interval's lower end (at most :data:`B_REALISTIC`), if the larger root of its upper
    end (or where the roots meet, beyond the largest deficit any B explains) is a realistic rig: B at most
    :data:`B_REALISTIC`, Kce at least :data:`KCE_REALISTIC`."""
    ends = (d, d - Z95 * sigma, d + Z95 * sigma)
    fits = [_roots(runs, runs.Kq * float(np.exp(x))) if x > 0 else (0.0, (math.inf, 0.0), True) for x in ends]
    (b, other, exact), (lo, (top, _), explained), (hi, nearest, _) = fits  # nearest: the larger root closest
    widened = explained and ends[1] > 0 and nearest[0] <= B_REALISTIC and nearest[1] >= KCE_REALISTIC
    if widened:
        hi = max(hi, min(top, B_REALISTIC))
    # the deficit's own larger root, where it is another realistic rig inside the interval
    larger = widened and exact and b < other[0] <= B_REALISTIC and other[1] >= KCE_REALISTIC
    return b, lo, hi, explained and lo > 0, other[0] if larger else None


def _rel_se(est: Estimate) -> float:
    """Relative standard error [-] that a normal 95 % interval as wide as ``est``'s has: (hi − lo)/(2·Z95·value).
    A static test's interval is Student's t of its own degrees of freedom (the calibration's Kpot has 8, the flow
    test about 30), so its heavier tails widen the standard error the deficit's z is counted in; inf where the
    interval is not finite (too few readings: the test can then show no deficit)."""
    lo, hi = est.interval
    width = hi - lo
    return float(width / (2 * Z95 * abs(est.value))) if est.value != 0 and np.isfinite(width) else math.inf


def _log_se(v: Value) -> float:
    """Standard error of ln(value) that a normal 95 % interval as wide as the runs' ``v`` has (0 without one): its
    interval is symmetric in ln, built with the t quantile of the runs' jackknife (5 degrees of freedom for 6 runs,
    :func:`grader.gap.build.value`)."""
    if v.interval is None or v.interval[0] <= 0:
        return 0.0
    return float(np.log(v.interval[1] / v.interval[0])) / (2 * Z95)


def _kpot_se(ds: Dataset) -> float:
    """:func:`_rel_se` of the calibration's Kpot where the loop gain carries it (volts feedback), else 0."""
    if ds.manifest.feedback != "volts" or ds.calibration is None:
        return 0.0
    from grader.identify import PotCalibration

    try:
        k = PotCalibration().fit(ds.calibration["position"], ds.calibration["voltage"]).Kpot_
    except (IdentificationError, ValueError, ArithmeticError):
        return 0.0
    return _rel_se(k)


def loop_gain(ds: Dataset, cand: Candidate, base: RigParams) -> LoopGainInfo | None:
    """The flow test's Kq against the Kq of candidate ``cand`` fitted to the runs (its linear model around
    ``base``), and the viscous friction that reconciles them (module docstring); None without a usable flow test,
    or where the flow test's or the calibration's interval is not finite (no deficit could be told from noise)."""
    if ds.flow_test is None:
        return None
    from grader.identify.flow import FlowGainFit

    try:
        flow = FlowGainFit(Kamp=ds.given["Kamp"]).fit(ds.flow_test["input"], ds.flow_test["flow"]).Kq_
    except (IdentificationError, ValueError, ArithmeticError):
        return None
    if flow.status != "ok":
        return None
    runs = base.with_(**{k: v.value for k, v in cand.linear_params.items()})
    runs_kq = cand.linear_params["Kq"]
    flow_kq = build.value(flow.value, "in**3/s/mA", flow.interval)
    d = float(np.log(flow.value / runs.Kq))
    sigma = float(np.sqrt(_rel_se(flow) ** 2 + _log_se(runs_kq) ** 2 + _kpot_se(ds) ** 2))
    if not np.isfinite(sigma):
        return None
    z = d / sigma if sigma > 0 else 0.0
    b, lo, hi, explained, larger = viscous_b(runs, d, sigma)
    return LoopGainInfo(flow_test_Kq=flow_kq, runs_Kq=runs_kq, candidate=cand.effect,
                        deficit=build.r6(1.0 - float(np.exp(-d))), deficit_z=build.r6(z),
                        viscous_B=build.value(b, "lbf*s/in", (lo, hi)), names_viscous=names_viscous(z, explained),
                        viscous_B_larger_root=None if larger is None else build.value(larger, "lbf*s/in"))


def names_viscous(z: float, explained: bool) -> bool:
    """Whether a loop-gain deficit of ``z`` standard errors names viscous friction: at least :data:`DEFICIT_Z`, and
    a B within the deficit's 95 % interval explains it exactly (:func:`viscous_b`; beyond the largest deficit any
    B explains, B is the closest, at the interval's top)."""
    return z >= DEFICIT_Z and explained


def viscous_unexcluded(verdict: Verdict, fr: Friction | None, lg: LoopGainInfo | None) -> Verdict:
    """A ``none`` verdict lists viscous friction as not ruled out when no static test rules out a visible B:
    no friction test, and no flow test or a loop gain whose B interval reaches :data:`VISIBLE` of the range's top."""
    top = EFFECTS["viscous_friction"].params[0].typical[1]
    if verdict.effect != NONE or fr is not None or "viscous_friction" in verdict.not_ruled_out:
        return verdict
    if lg is not None and (lg.viscous_B.interval or (0.0, 0.0))[1] < VISIBLE * top:
        return verdict
    upto = "" if lg is None or lg.viscous_B.interval is None else f" up to B = {lg.viscous_B.interval[1]:.3g} lbf·s/in"
    test = separating_test(NONE, ["viscous_friction"])
    return verdict.model_copy(update={
        "not_ruled_out": [*verdict.not_ruled_out, "viscous_friction"],
        "separating_test": verdict.separating_test or test,
        "explanation": f"{verdict.explanation}; viscous friction{upto} cannot be ruled out without a friction test "
                       f"(in the closed loop it acts as a larger Kce): {would(test, 'show it')}"})


def viscous_from_loop_gain(verdict: Verdict, lg: LoopGainInfo | None) -> Verdict:
    """Viscous friction as the verdict (the runs name nothing) or as its second effect (the runs name one effect,
    whose fit gave the Kq compared) when the loop gain shows it (module docstring). The ADC, seen in the readings
    themselves, comes first (:func:`quantized`, applied before): where it took the place viscous friction would
    take (the runs name nothing, or one effect and the ADC is beside it), the deficit is told in the explanation
    and viscous friction is not named. The runs' fits have no ADC in their loop, so their Kq carries what the ADC
    does: an independent simulator's 25.7 mA current limit with a 10-bit ADC showed a deficit of 3.6 % (2.9
    standard errors) with no viscous friction, and was named a current limit with viscous friction."""
    runs_named = NONE if verdict.effect == QUANTIZATION else verdict.effect  # the ADC is named from the readings
    if (lg is None or not lg.names_viscous or lg.candidate != runs_named
            or "viscous_friction" in (verdict.effect, verdict.second_effect)):
        return verdict
    b, iv = lg.viscous_B.value, lg.viscous_B.interval or (lg.viscous_B.value,) * 2
    shown = (f"the runs' loop gain is {100 * lg.deficit:.2g} % below the flow test's Kq ({lg.deficit_z:.2g} "
             f"standard errors): viscous friction B = {b:.3g} lbf·s/in (95 % interval {iv[0]:.3g} to {iv[1]:.3g}) "
             "reconciles them")
    if QUANTIZATION in (verdict.effect, verdict.second_effect):
        return verdict.model_copy(update={"not_named": [*verdict.not_named, "viscous_friction"], "explanation": (
            f"{verdict.explanation}; {shown}, but viscous friction is not named: the runs' fits lack the ADC, which "
            f"biases their Kq; {would(separating_test(NONE, ['viscous_friction']), 'show it')}")})
    if verdict.second_effect is not None:
        return verdict
    return _add(verdict, "viscous_friction", f"{shown}, which the runs alone take for a larger Kce and a smaller Kq")
