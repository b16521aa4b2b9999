"""Evidence beside the closed-loop runs that names an effect: the friction test and a quantising ADC.

* **Friction test** (force against speed, :class:`grader.identify.FrictionFit`): its slope is the
  viscous friction B and its intercept the Coulomb level Fc, each with a 95 % interval from the
  regression. Viscous friction acts in the closed loop almost exactly as a larger Kce, so the
  runs alone cannot name it; the friction test can. It is named when B's interval excludes 0
  and B reaches :data:`VISIBLE` of its realistic range's top. The Coulomb level breaks a tie:
  when the runs cannot tell Coulomb friction from the verdict (a deadband or backlash looks alike
  in closed loop), a friction test whose Fc is clearly above 0 and inside the fitted Coulomb
  candidate's interval makes Coulomb friction the verdict.
* **ADC** (:mod:`grader.gap.quantization`): named when its step matters.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from grader.datasets import Dataset
from grader.errors import IdentificationError
from grader.gap import build
from grader.gap.candidates import NONE
from grader.gap.quantization import Quantization
from grader.gap.schema import Candidate, Value, Verdict
from grader.gap.verdict import Ranking
from grader.model.effects import EFFECTS

VISIBLE = 0.1  # of the realistic range's top


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
    """``name`` as the verdict (if it is none) or as its second effect (if that is free)."""
    if verdict.effect == NONE:
        return verdict.model_copy(update={"effect": name, "shares": {name: 1.0}, "explanation": text,
                                          "indistinguishable_from": [], "separating_test": None})
    if verdict.second_effect is None:  # no share of the held-out shrink: it is not fitted to the runs
        return verdict.model_copy(update={"second_effect": name, "shares": {**verdict.shares, name: 0.0},
                                          "explanation": f"{verdict.explanation}; and {text}"})
    return verdict


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
           f"so the tie goes to coulomb_friction")
    return replace(rk, order=order, verdict=c, runner_up=old, margin=0.0, ties=ties), why


def viscous(verdict: Verdict, fr: Friction | None) -> Verdict:
    """Viscous friction named from the friction test when it shows B (module docstring)."""
    if fr is None or not fr.shows("viscous_friction") or "viscous_friction" in (verdict.effect, verdict.second_effect):
        return verdict
    return _add(verdict, "viscous_friction",
                f"the friction test shows viscous friction B = {fr.B[0]:.3g} lbf·s/in (95 % interval "
                f"{fr.B[1]:.3g} to {fr.B[2]:.3g}); in the closed loop it acts as a larger Kce")


def quantized(verdict: Verdict, quant: Quantization | None) -> Verdict:
    """sensor_quantization named when the ADC matters."""
    if quant is None or not quant.matters:
        return verdict
    return _add(verdict, "sensor_quantization", quant.text())
