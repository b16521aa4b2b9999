"""Error carried forward: recompute a dependent value from the student's own upstream values.

``RECOMPUTE[key quantity]`` names the upstream items a value is computed from and how:
β/Vt and Kce by the students' coefficient matching (from ω, Kp_crit, Kq, Kpot); the
predicted gains, ramp error and closed-loop poles from the student's own linear model
(Kq, Kpot, β/Vt, Kce with the key's A, M, Kamp, B and sample time). Upstream items the
student did not answer (or that could not be read) take the key's values.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from grader.errors import GraderError
from grader.grading.context import KeyContext
from grader.model.params import Controller, RigParams


@dataclass(frozen=True)
class Recompute:
    """The upstream items a key quantity depends on and the function recomputing it."""

    inputs: tuple[str, ...]
    compute: Callable[[KeyContext, Mapping[str, float]], Any]


def _upstream(kc: KeyContext, own: Mapping[str, float], names: tuple[str, ...]) -> dict[str, float]:
    return {n: float(own[n]) if n in own else float(kc.value(n)) for n in names}


def _matching(which: int) -> Callable[[KeyContext, Mapping[str, float]], float]:
    def compute(kc: KeyContext, own: Mapping[str, float]) -> float:
        from grader.identify.critical import coefficient_match

        u = _upstream(kc, own, _MATCH_INPUTS)
        x = kc.matching_inputs()
        k_fb = u["Kpot"] if kc.key.feedback == "volts" else 1.0
        return coefficient_match(omega=u["omega_crit"], kp_crit=u["Kp_crit"], A=x["A"], M=x["M"], Kamp=x["Kamp"],
                                 Kq=u["Kq"], k_fb=k_fb, B=x["B"])[which]
    return compute


NAN = float("nan")


def _or_nan(value: float | None) -> float:
    return NAN if value is None else value


def student_model(kc: KeyContext, own: Mapping[str, float]) -> RigParams:
    """The key's model with the student's Kq, Kpot, β/Vt and Kce."""
    u = _upstream(kc, own, _MODEL_INPUTS)
    return kc.params().with_(**u)


def _prediction(kind: str) -> Callable[[KeyContext, Mapping[str, float]], Any]:
    def compute(kc: KeyContext, own: Mapping[str, float]) -> Any:
        from grader.model import zloop  # scipy.signal, python-control: only when a prediction is recomputed
        from grader.model.linear import closed_loop_poles, ramp_error

        p = student_model(kc, own)
        if kind == "no_overshoot":
            return _or_nan(zloop.gain_no_overshoot(p))
        if kind == "25":
            return _or_nan(zloop.gain_for_overshoot(p, 0.25))
        if kind == "ramp":
            inputs = kc.key.quantities["ramp_ess_P"].inputs
            if "Kp" not in inputs:
                return None  # no P ramp run to predict
            kp = float(inputs["Kp"])
            return ramp_error(p, kp, float(inputs["ramp rate [in/s]"])) if kp < zloop.critical_gain(p) else NAN
        return [{**run, "poles": [[z.real, z.imag] for z in closed_loop_poles(p, Controller(run["Kp"], run["Ki"], run["Kd"]))]}
                for run in kc.value("closed_loop_poles")]
    return compute


_MATCH_INPUTS = ("omega_crit", "Kp_crit", "Kq", "Kpot")
_MODEL_INPUTS = ("Kq", "Kpot", "beta_over_Vt", "Kce")

RECOMPUTE: dict[str, Recompute] = {
    "beta_over_Vt": Recompute(_MATCH_INPUTS, _matching(0)),
    "Kce": Recompute(_MATCH_INPUTS, _matching(1)),
    "Kp_no_overshoot": Recompute(_MODEL_INPUTS, _prediction("no_overshoot")),
    "Kp_25_overshoot": Recompute(_MODEL_INPUTS, _prediction("25")),
    "ramp_ess_P": Recompute(_MODEL_INPUTS, _prediction("ramp")),
    "closed_loop_poles": Recompute(_MODEL_INPUTS, _prediction("poles")),
}


def recompute(key_name: str, kc: KeyContext, own: Mapping[str, float]) -> Any:
    """The value ``key_name`` takes with the student's upstream values ``own`` (key units): NaN
    when with them it does not exist (not reachable), None when it cannot be recomputed."""
    spec = RECOMPUTE.get(key_name)
    if spec is None:
        return None
    try:
        return spec.compute(kc, {k: v for k, v in own.items() if k in spec.inputs})
    except (GraderError, ArithmeticError, ValueError, TypeError):  # TypeError: a null key value (not identifiable)
        return None
