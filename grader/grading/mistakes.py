"""The catalog of known mistakes: each recomputes the wrong answer a mistake produces.

A mistake's ``compute(env, item)`` returns the value the mistaken procedure gives, in
the key's unit (a float), as a pole set, or as an exact rational function for the
transfer-function items; the checker compares the answer with it at the item's
tolerance. Wrong values are recomputed from the key's inputs and the dataset (flow
and friction data) rather than typed in as factors.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from grader.errors import GraderError
from grader.grading import tf
from grader.grading.context import KeyContext
from grader.model.params import G_IN_PER_S2, Feedback


@dataclass(frozen=True)
class Env:
    """What a mistake is recomputed from: the key context (None for the prelab) and the TF convention."""

    kc: KeyContext | None
    convention: Feedback


@dataclass(frozen=True)
class Mistake:
    """A known mistake: the items it applies to, default feedback, and how to recompute it."""

    code: str
    items: tuple[str, ...]
    feedback: str
    compute: Callable[[Env, str], Any]


def _match(kc: KeyContext, *, typo: bool = False, **overrides: float) -> tuple[float, float]:
    """(β/Vt, Kce) by the students' coefficient matching with some inputs changed."""
    from grader.identify.critical import coefficient_match

    x = {**kc.matching_inputs(), **overrides}
    k_fb = x.pop("k_fb", kc.k_fb)
    x.pop("Kpot")
    if typo:  # the paper's eq. (4) constant term ω² (not a·ω²) solved for β/Vt
        kc_gain = x["kp_crit"] * x["Kamp"] * k_fb * x["Kq"]
        return x["omega"] ** 2 * x["M"] / (4.0 * kc_gain * x["A"]), math.nan
    return coefficient_match(omega=x["omega"], kp_crit=x["kp_crit"], A=x["A"], M=x["M"], Kamp=x["Kamp"],
                             Kq=x["Kq"], k_fb=k_fb, B=x["B"])


def _matched(**overrides: Any) -> Callable[[Env, str], float | None]:
    """β/Vt or Kce from coefficient matching with ``overrides`` computed from the key context."""
    def compute(env: Env, item: str) -> float | None:
        if env.kc is None:
            return None
        kc = env.kc
        kw = {k: (v(kc) if callable(v) else v) for k, v in overrides.items()}
        bv, kce = _match(kc, **kw)
        return bv if item == "beta_over_Vt" else kce
    return compute


def _area(kc: KeyContext, *, as_radius: bool = False, rod: bool = True) -> float:
    g = kc.given
    d_bore, d_rod = g["bore"], (g["rod"] if rod else 0.0)
    return math.pi * (d_bore**2 - d_rod**2) * (1.0 if as_radius else 0.25)


def _kpot_factor(kc: KeyContext) -> float:
    """Factor on gains and ramp errors when Kpot is left out of (volts) or put into (inches) the loop."""
    kpot = kc.value("Kpot")
    return kpot if kc.key.feedback == "volts" else 1.0 / kpot


def _flow_unsubtracted(env: Env, item: str) -> float | None:
    """Kq from a line through the signed readings with the leakage left in."""
    from grader.identify.flow import FlowGainFit

    if env.kc is None or env.kc.dataset.flow_test is None:
        return None
    v, q = env.kc.dataset.flow_test["input"], env.kc.dataset.flow_test["flow"]
    kamp = env.kc.given["Kamp"]
    fit = FlowGainFit(Kamp=kamp).fit(v, q)
    if fit.Kq_.status != "ok":
        return None
    i = kamp * v
    signed = np.sign(i - fit.null_current_.value) * q
    return float(np.polyfit(i[fit.linear_mask_], signed[fit.linear_mask_], 1)[0])


def _b_through_origin(env: Env, item: str) -> float | None:
    """B as the slope of force on speed through the origin (friction taken as viscous)."""
    if env.kc is None or env.kc.dataset.friction is None:
        return None
    v, f = env.kc.dataset.friction["speed"], env.kc.dataset.friction["force"]
    return float(np.dot(v, f) / np.dot(v, v))


def _scaled(factor: Callable[[KeyContext], float]) -> Callable[[Env, str], Any]:
    def compute(env: Env, item: str) -> Any:
        if env.kc is None:
            return None
        value, f = env.kc.value(item), factor(env.kc)
        if item == "closed_loop_poles":
            return [{**run, "poles": [[re * f, im * f] for re, im in run["poles"]]} for run in value]
        return value * f
    return compute


def _open_loop_poles(env: Env, item: str) -> Any:
    """Poles of L(s) (0 and the roots of s² + a2·s + a1) given for every gain."""
    if env.kc is None:
        return None
    a2, a1 = env.kc.value("char_poly_a2"), env.kc.value("char_poly_a1")
    ol = [[0.0, 0.0]] + [[r.real, r.imag] for r in np.roots([1.0, a2, a1])]
    return [{**run, "poles": ol} for run in env.kc.value("closed_loop_poles")]


def _tf(code: str) -> Callable[[Env, str], Any]:
    return lambda env, item: tf.reference(item, env.convention, code)


_BV_KCE = ("beta_over_Vt", "Kce")
_PRED = ("Kp_no_overshoot", "Kp_25_overshoot", "ramp_ess_P")

CATALOG: dict[str, Mistake] = {m.code: m for m in (
    Mistake("leakage_not_subtracted", ("Kq",), "The flow meter's reading includes the valve's internal leakage: "
            "subtract the leakage (the lowest reading, at the spool's centre) before fitting the slope.", _flow_unsubtracted),
    Mistake("kamp_left_out", ("Kq",), "Kq is flow per milliampere of valve current: convert the amplifier input "
            "volts to current with Kamp before fitting.", _scaled(lambda kc: kc.given["Kamp"])),
    Mistake("kpot_inverted", ("Kpot",), "Kpot is volts per inch (voltage change over the distance moved), not inches per volt.",
            lambda env, item: None if env.kc is None else 1.0 / env.kc.value("Kpot")),
    Mistake("b_through_origin", ("B",), "The friction data are dominated by Coulomb friction (a constant force), "
            "so the model takes B = 0; a line through the origin mistakes Coulomb friction for damping.", _b_through_origin),
    Mistake("hz_as_rad_s", ("omega_crit", "closed_loop_poles"), "The frequency read off the plot is in Hz (cycles per "
            "second); multiply by 2π for rad/s.", _scaled(lambda kc: 1.0 / (2.0 * math.pi))),
    Mistake("omega_in_hz", _BV_KCE, "The coefficient matching needs ω in rad/s; it looks like the frequency in Hz was used.",
            _matched(omega=lambda kc: kc.matching_inputs()["omega"] / (2.0 * math.pi))),
    Mistake("weight_as_mass", _BV_KCE, "The 29 lb is a weight: the mass is W/g = 29 lbf / 386.1 in/s² in lbf·s²/in.",
            _matched(M=lambda kc: kc.matching_inputs()["M"] * G_IN_PER_S2)),
    Mistake("diameter_as_radius", _BV_KCE, "The area uses the diameters as radii: A = π/4·(D² − d²).",
            _matched(A=lambda kc: _area(kc, as_radius=True))),
    Mistake("bore_without_rod", _BV_KCE, "The piston area is the bore area minus the rod area (a through rod): "
            "A = π/4·(D² − d²).", _matched(A=lambda kc: _area(kc, rod=False))),
    Mistake("missing_factor_4", ("beta_over_Vt", *tf.FORMS), "Merritt's continuity equation has Vt/(4β): the "
            "factor 4 is missing.", lambda env, item: _missing_4(env, item)),
    Mistake("paper_typo_constant_term", ("beta_over_Vt",), "The paper's eq. (4) has a typo: the constant term of "
            "(s + a)(s² + ω²) is a·ω², not ω².", _matched(typo=True)),
    Mistake("kpot_convention", ("Kce", *_PRED, *tf.FORMS), "Check where Kpot sits in the loop: with the pot voltage "
            "fed back it multiplies the loop gain; with the error in inches it does not.",
            lambda env, item: (tf.reference(item, env.convention, "kpot_convention") if item in tf.FORMS
                               else _kpot_mistake(env, item))),
    Mistake("open_loop_poles", ("closed_loop_poles",), "These are the poles of the open loop L(s); the closed-loop "
            "poles are the roots of 1 + L(s) = 0 at each gain.", _open_loop_poles),
    Mistake("damping_omitted", tf.FORMS, "B was dropped; keep the damping term B in the prelab model.", _tf("damping_omitted")),
    Mistake("open_loop_given", ("closed_loop_tf",), "This is the open-loop transfer function; close the loop: L/(1 + L).",
            _tf("open_loop_given")),
    Mistake("closed_loop_given", ("open_loop_tf",), "This is the closed-loop transfer function; the open loop is the "
            "product of the blocks around the loop.", _tf("closed_loop_given")),
    Mistake("positive_feedback", ("closed_loop_tf", "char_poly"), "The feedback is negative: the closed loop is "
            "L/(1 + L), not L/(1 − L).", _tf("positive_feedback")),
)}


def _kpot_mistake(env: Env, item: str) -> float | None:
    if env.kc is None:
        return None
    if item == "Kce":
        return _matched(k_fb=lambda kc: 1.0 if kc.key.feedback == "volts" else kc.value("Kpot"))(env, item)
    return env.kc.value(item) * _kpot_factor(env.kc)


def _missing_4(env: Env, item: str) -> Any:
    """Without Merritt's 4 the s coefficient gives β/Vt·A²/M = ω², i.e. 4× the β/Vt."""
    if item in tf.FORMS:
        return tf.reference(item, env.convention, "missing_factor_4")
    value = _matched()(env, item)
    return None if value is None else 4.0 * value


def wrong_value(code: str, env: Env, item: str) -> Any:
    """The value mistake ``code`` gives for ``item`` (None when it cannot be computed here);
    memoised in the key context (or, for the prelab, by :func:`tf.reference`)."""
    memo = env.kc.memo if env.kc is not None else {}
    tag = ("mistake", code, item, env.convention)
    if tag not in memo:
        try:
            memo[tag] = CATALOG[code].compute(env, item)
        except (GraderError, ArithmeticError, ValueError, KeyError):
            memo[tag] = None
    return memo[tag]
