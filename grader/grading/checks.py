"""Checking one answer item: dispatch by kind; numbers with units and transfer functions.

Verdict order: missing → invalid → wrong_dimension → correct; a wrong answer is then
explained by error carried forward or a known mistake, whichever earns most (ties in
that order), else by a unit slip, else it is incorrect.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

from grader.errors import ExpressionError
from grader.grading import ecf, tf
from grader.grading import feedback as fb
from grader.grading.answers import AnswerError, Gains, is_blank, read_quantity, to_unit
from grader.grading.context import KeyContext
from grader.grading.designs import RigVerdict
from grader.grading.expressions import parse_expression, to_ratfunc
from grader.grading.items import ITEMS
from grader.grading.limits import Limits, time_limit
from grader.grading.mistakes import CATALOG, Env, wrong_value
from grader.grading.results import READ_STATUSES, ItemResult
from grader.grading.rubric import Rubric, RubricItem
from grader.grading.units_diagnosis import diagnose_slip
from grader.model.params import Feedback
from grader.units import Q_, dimension_words, parse_quantity, pretty_unit


@dataclass(frozen=True)
class CheckEnv:
    """Everything a check needs; ``kc`` is None when no lab data is available (prelab only)."""

    rubric: Rubric
    kc: KeyContext | None
    convention: Feedback
    reveal: bool
    limits: Limits
    rig: Callable[[str, Gains], RigVerdict | None]

    @property
    def mistake_env(self) -> Env:
        return Env(self.kc, self.convention)


def result(name: str, item: RubricItem, status: str, credit: float, text: str, *, mistake: str | None = None,
           detail: Mapping[str, Any] | None = None, value: Any = None) -> ItemResult:
    """An ItemResult earning ``credit`` (a fraction) of the item's points."""
    return ItemResult(item=name, status=status, points=credit * item.points, max_points=item.points,  # type: ignore[arg-type]
                      feedback=text, mistake=mistake, detail=dict(detail or {}), value=value)


def best(cands: list[ItemResult], fallback: ItemResult) -> ItemResult:
    """The explanation earning most points (first listed wins ties), else the fallback."""
    return max(cands, key=lambda r: r.points, default=fallback) if cands else fallback


def mistake_text(item: RubricItem, code: str) -> str:
    ref = next(m for m in item.mistakes if m.code == code)
    return ref.feedback or CATALOG[code].feedback


def needs_key(name: str) -> bool:
    return ITEMS[name].kind != "expression"


# ------------------------------------------------------------------ quantities
@lru_cache(maxsize=256)
def _absolute(a: str | float | None, key_unit: str, unit: str) -> float:
    """A tolerance's absolute part in the compared (key) unit."""
    if a is None:
        return 0.0
    q = parse_quantity(a, where="tolerance.absolute", default_unit=unit)
    return to_unit(q, key_unit) or 0.0


def _given(raw: Any, unit: str) -> str:
    """The answer as the student wrote it, its unit in the course's style (a bare number: the unit it was taken in)."""
    text = raw.strip() if isinstance(raw, str) else f"{raw:g}"
    m = re.fullmatch(r"([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(.*)", text)
    if m is None:
        return text
    if m.group(2):
        return f"{m.group(1)} {pretty_unit(m.group(2))}"
    return text if unit == "dimensionless" else f"{text} (taken in {pretty_unit(unit)})"


def _ecf_candidate(name: str, item: RubricItem, env: CheckEnv, done: Mapping[str, ItemResult],
                   accept: Callable[[float, float], bool], v: float, given: str) -> ItemResult | None:
    assert env.kc is not None
    read = {d: done[d] for d in item.depends_on if d in done and done[d].status in READ_STATUSES}
    wrong = [d for d, r in read.items() if r.status != "correct"]
    if not wrong:
        return None
    target = ecf.recompute(env.rubric.key_name(name), env.kc, {d: r.value for d, r in read.items()})
    if not isinstance(target, float) or not math.isfinite(target) or not accept(v, target):
        return None
    kname = env.rubric.key_name(name)
    unit = item.unit or env.kc.unit(kname)
    expected = env.kc.value(kname) if env.reveal and env.kc.key.quantities[kname].reachable else None
    return result(name, item, "correct_ecf", item.ecf_credit, fb.ecf(name, given, wrong, expected, unit),
                  mistake="ecf", detail={"recomputed": target, "from": wrong}, value=v)


def check_quantity(name: str, raw: Any, env: CheckEnv, done: Mapping[str, ItemResult]) -> ItemResult:
    item = env.rubric.items[name]
    if is_blank(raw):
        return result(name, item, "missing", 0.0, fb.missing(name))
    assert env.kc is not None
    kname = env.rubric.key_name(name)
    entry = env.kc.key.quantities[kname]
    key_unit, unit = entry.unit, item.unit or entry.unit
    try:
        q = read_quantity(raw, unit=unit, what=name)
    except AnswerError as exc:
        return result(name, item, "invalid", 0.0, fb.invalid(name, str(exc)), detail={"error": str(exc)})
    given = _given(raw, unit)
    v = to_unit(q, key_unit)
    if v is None:
        text = fb.wrong_dimension(name, given, dimension_words(q.units), unit, dimension_words(unit))
        return result(name, item, "wrong_dimension", 0.0, text, detail={"unit_given": str(q.units), "unit_expected": unit})
    absolute = _absolute(item.tolerance.absolute, key_unit, unit)
    accept = lambda x, e: item.tolerance.accepts(x, e, absolute=absolute)  # noqa: E731
    if not entry.reachable:  # a number for a value the rig does not have
        text = fb.number_not_reachable(name, given, entry.reason if env.reveal else None)
        fallback = result(name, item, "incorrect", 0.0, text, detail={"value": v, "unit": key_unit,
                                                                       "key_status": entry.status}, value=v)
        return _ecf_candidate(name, item, env, done, accept, v, given) or fallback
    expected = float(entry.value)
    detail = {"value": v, "unit": key_unit, "expected": expected, "tolerance": item.tolerance.describe(unit)}
    alts = [float(env.kc.value(a)) for a in item.also_accept if env.kc.key.quantities[a].reachable]
    if item.tolerance.accepts(v, expected, absolute=absolute, interval=entry.interval) or any(accept(v, a) for a in alts):
        return result(name, item, "correct", 1.0, fb.correct(name, given), detail=detail, value=v)
    shown_expected = to_unit(Q_(expected, key_unit), unit)
    reveal = shown_expected if env.reveal else None
    cands = [c for c in [_ecf_candidate(name, item, env, done, accept, v, given)] if c]
    for m in item.mistakes:
        w = wrong_value(m.code, env.mistake_env, kname)
        if isinstance(w, float) and math.isfinite(w) and accept(v, w):
            text = fb.known_mistake(name, given, mistake_text(item, m.code), reveal, unit)
            cands.append(result(name, item, "known_mistake", m.credit, text, mistake=m.code,
                                detail={**detail, "mistake_value": w}, value=v))
    v_unit = to_unit(q, unit)
    slip = None
    if v_unit and shown_expected:
        slip = diagnose_slip(v_unit, shown_expected, unit, rel_tol=item.tolerance.relative or 0.02)
    if slip is not None and not cands:
        code = f"unit_slip:{slip.used}->{slip.needed}"
        cands.append(result(name, item, "unit_mismatch", item.unit_mismatch_credit, fb.unit_slip(name, slip, reveal, unit),
                            mistake=code, detail={**detail, "unit_used": slip.used, "unit_expected": slip.needed,
                                                  "factor": slip.factor}, value=v))
    fallback = result(name, item, "incorrect", 0.0, fb.incorrect(name, given, item.tolerance, unit, reveal),
                      detail=detail, value=v)
    return best(cands, fallback)


# ------------------------------------------------------------------ expressions
@lru_cache(maxsize=4096)
def tf_verdict(form: str, convention: Feedback, text: str, codes: tuple[str, ...],
               limits: Limits, reveal: bool = True) -> tuple[str, str | None, tuple[str, ...]]:
    """(status, mistake code, notes) of a transfer-function answer; ``invalid`` carries the reason.
    Pure in its arguments, hence cached (many students submit the same text)."""
    ref = tf.reference(form, convention)
    wrongs = [(code, tf.reference(form, convention, code)) for code in codes]
    try:
        expr = parse_expression(text, limits=limits)
        with time_limit(limits.expr_seconds, fb.name(form)):
            answer = to_ratfunc(expr)
            if tf.equivalent(form, answer, ref):
                return "correct", None, ()
            for code, wrong in wrongs:
                if tf.equivalent(form, answer, wrong):
                    return "known_mistake", code, ()
            return "incorrect", None, tuple(tf.diagnose(form, answer, ref, expr.symbols,
                                                        tf.reference_symbols(form, convention), reveal=reveal))
    except ExpressionError as exc:
        return "invalid", None, (str(exc),)
    except Exception as exc:  # noqa: BLE001 - an unexpected failure invalidates only this answer
        return "invalid", None, (unchecked_reason(exc),)


def unchecked_reason(exc: BaseException) -> str:
    """The generic, student-facing reason for an answer whose check failed unexpectedly."""
    return f"this answer could not be checked: {type(exc).__name__}"


def check_expression(name: str, raw: Any, env: CheckEnv) -> ItemResult:
    item = env.rubric.items[name]
    if is_blank(raw):
        return result(name, item, "missing", 0.0, fb.missing(name))
    if not isinstance(raw, str) or len(raw) > env.limits.max_string:
        reason = (f"expected the expression as text, got {type(raw).__name__}" if not isinstance(raw, str)
                  else f"expression longer than {env.limits.max_string} characters")
        return result(name, item, "invalid", 0.0, fb.invalid(name, reason), detail={"error": reason})
    codes = tuple(m.code for m in item.mistakes)
    status, code, notes = tf_verdict(name, env.convention, raw, codes, env.limits, env.reveal)
    detail: dict[str, Any] = {"convention": env.convention}
    if status == "correct":
        return result(name, item, "correct", 1.0, f"{fb.name(name)}: correct (equivalent to the model's).", detail=detail)
    if status == "known_mistake" and code is not None:
        credit = next(m.credit for m in item.mistakes if m.code == code)
        return result(name, item, "known_mistake", credit, f"{fb.name(name)}: {mistake_text(item, code)}",
                      mistake=code, detail=detail)
    if status == "invalid":
        text = (f"{fb.name(name)}: {notes[0]}." if notes[0].startswith("this answer could not be checked")
                else fb.invalid(name, notes[0]))
        return result(name, item, "invalid", 0.0, text, detail={"error": notes[0]})
    text = f"{fb.name(name)} is not equivalent to the model's ({env.convention} feedback convention): " + "; ".join(notes) + "."
    return result(name, item, "incorrect", 0.0, text, detail={**detail, "differences": list(notes)})
