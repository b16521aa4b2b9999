"""Student-facing sentences. With ``reveal`` False (``grader check``) no key value, no number
computed from the key and no reference expression is ever written."""

from __future__ import annotations

import re

from grader.grading.rubric import Tolerance
from grader.grading.units_diagnosis import Slip
from grader.units import fmt, pretty_unit

NAMES: dict[str, str] = {
    "closed_loop_tf": "closed-loop transfer function", "open_loop_tf": "open-loop transfer function",
    "char_poly": "characteristic polynomial", "beta_over_Vt": "β/Vt", "omega_crit": "ω at the limit of stability",
    "Kp_crit": "critical gain", "Kp_no_overshoot": "highest gain without overshoot",
    "Kp_25_overshoot": "gain for 25 % overshoot", "ramp_ess_P": "ramp steady-state error (P)",
    "closed_loop_poles": "closed-loop poles", "pd_design": "PD design", "pi_design": "PI design",
}


def name(item: str) -> str:
    return NAMES.get(item, item)


def shown(value: float, unit: str) -> str:
    return fmt(value, unit)


def missing(item: str) -> str:
    return f"No answer for {name(item)}."


def invalid(item: str, reason: str) -> str:
    """The reader's reason without repeating the item's name."""
    return f"{name(item)}: could not read your answer: {reason.removeprefix(f'{item}: ')}"


def wrong_dimension(item: str, given: str, given_dim: str, unit: str, dim: str) -> str:
    """``Kpot = 0.85 V/s: V/s is a voltage per time; Kpot needs a voltage per length (V/in).``"""
    written = re.sub(r"^\s*[-+]?[\d.]+([eE][-+]?\d+)?\s*", "", given) or "a bare number"
    return (f"{name(item)} = {given}: {written} is {given_dim}; {name(item)} needs {dim} "
            f"({pretty_unit(unit) or 'no unit'}).")


def correct(item: str, given: str) -> str:
    return f"{name(item)} = {given}: correct."


def incorrect(item: str, given: str, tol: Tolerance, unit: str, expected: float | None) -> str:
    if expected is None:
        return (f"{name(item)} = {given} does not match the value from your station's data "
                f"(tolerance {tol.describe(unit)}). Recheck the procedure and the units.")
    return f"{name(item)} = {given} is not within {tol.describe(unit)} of the expected {shown(expected, unit)}."


def ecf(item: str, given: str, upstream: list[str], expected: float | None, unit: str) -> str:
    ups = ", ".join(name(u) for u in upstream)
    tail = f" (The key's value is {shown(expected, unit)}.)" if expected is not None else ""
    return (f"{name(item)} = {given} differs from the key, but it follows correctly from your own {ups} "
            f"(error carried forward).{tail}")


def unit_slip(item: str, slip: Slip, expected: float | None, unit: str) -> str:
    tail = f" Expected {shown(expected, unit)}." if expected is not None else ""
    return slip.message(name(item), reveal_factor=expected is not None) + "." + tail


def known_mistake(item: str, given: str, text: str, expected: float | None, unit: str) -> str:
    tail = f" (Expected {shown(expected, unit)}.)" if expected is not None else ""
    return f"{name(item)} = {given}: {text}{tail}"


def number_not_reachable(item: str, given: str, reason: str | None) -> str:
    """A number for an item the identified rig does not have; ``reason`` (None: key hidden) says why."""
    if reason is not None:
        return (f"{name(item)} = {given}: the rig identified from your station's data has no such value "
                f"({reason}). Answer 'not reachable'.")
    return (f"{name(item)} = {given} does not match your station's data. Check whether such a value exists "
            f"for your rig at all; if it does not, answer 'not reachable'.")


def reachable_after_all(item: str, expected: float | None, unit: str) -> str:
    """A not-reachable answer for an item the identified rig does have."""
    tail = f" (expected {shown(expected, unit)})" if expected is not None else "; compute it"
    return f"{name(item)}: not reachable is incorrect: your station's data give this value{tail}."
