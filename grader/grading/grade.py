"""Grading one read submission against one key context: every rubric item, in dependency order."""

from __future__ import annotations

from collections.abc import Callable, Mapping, MutableMapping
from dataclasses import dataclass
from typing import Any

from grader.errors import GraderError, RubricError
from grader.grading import feedback as fb
from grader.grading.answers import Gains
from grader.grading.checks import (
    CheckEnv,
    check_expression,
    check_quantity,
    needs_key,
    result,
    unchecked_reason,
)
from grader.grading.context import KeyContext
from grader.grading.designs import RigCase, RigVerdict, rig_verdict
from grader.grading.items import ITEMS
from grader.grading.limits import DEFAULT_LIMITS, Limits
from grader.grading.results import ItemResult, Student, SubmissionResult
from grader.grading.rubric import Rubric
from grader.grading.structured import check_design, check_poles
from grader.grading.submissions import InvalidAnswer, Submission
from grader.model.params import Feedback
from grader.units import quantity_to_float, ureg

RigLookup = Mapping[RigCase, RigVerdict | None]


@dataclass(frozen=True)
class GradeOptions:
    """How to grade: the rubric, the TF convention, whether feedback may reveal the key, limits."""

    rubric: Rubric
    convention: Feedback
    reveal: bool = True
    limits: Limits = DEFAULT_LIMITS


def check_rubric_units(rubric: Rubric, kc: KeyContext) -> None:
    """Every quantity item's unit must have its key quantity's dimension (an instructor error otherwise);
    also-accepted key names must exist in every key."""
    for name, item in rubric.items.items():
        key = rubric.key_name(name)
        if key not in kc.key.quantities:
            continue  # the data lack what this quantity needs: the item says so when graded
        for alt in item.also_accept:
            if alt not in kc.key.quantities:
                raise RubricError(f"items.{name}.also_accept: the key has no quantity {alt!r}")
        if item.unit and ITEMS[name].kind == "quantity" and not _same_dimension(item.unit, kc.unit(key)):
            raise RubricError(f"items.{name}: unit {item.unit} does not have the dimension of the key's {kc.unit(key)}")


def _same_dimension(a: str, b: str) -> bool:
    return ureg.Unit(a).dimensionality == ureg.Unit(b).dimensionality


def _rig_lookup(opts: GradeOptions, kc: KeyContext | None, known: RigLookup) -> Callable[[str, Gains], RigVerdict | None]:
    def lookup(item: str, gains: Gains) -> RigVerdict | None:
        if kc is None:
            return None
        case = RigCase(kc.key.station, item, gains)
        if case not in known:
            spec = opts.rubric.items[item].design
            threshold = quantity_to_float(spec.limit_cycle, "in") if spec else 0.002
            verdict = rig_verdict(case, threshold=threshold)
            if isinstance(known, MutableMapping):  # a caller's memo (the web server's)
                known[case] = verdict
            return verdict
        return known[case]
    return lookup


def _check(name: str, raw: Any, env: CheckEnv, done: Mapping[str, ItemResult]) -> ItemResult:
    item = env.rubric.items[name]
    if isinstance(raw, InvalidAnswer):
        return result(name, item, "invalid", 0.0, fb.invalid(name, raw.reason), detail={"error": raw.reason})
    kind = ITEMS[name].kind
    key = env.rubric.key_name(name)
    if kind in ("quantity", "poles") and env.kc is not None and key not in env.kc.key.quantities and raw is not None:
        why = f"cannot be checked: the lab data this key was computed from lack what {key} needs (e.g. a P ramp run)"
        return result(name, item, "invalid", 0.0, fb.invalid(name, why), detail={"error": why})
    try:
        if kind == "expression":
            return check_expression(name, raw, env)
        if kind == "quantity":
            return check_quantity(name, raw, env, done)
        if kind == "poles":
            return check_poles(name, raw, env, done)
        return check_design(name, raw, env)
    except GraderError as exc:
        return result(name, item, "invalid", 0.0, fb.invalid(name, str(exc)), detail={"error": str(exc)})
    except Exception as exc:  # noqa: BLE001 - an unexpected failure invalidates only this item
        why = unchecked_reason(exc)
        return result(name, item, "invalid", 0.0, f"{fb.name(name)}: {why}.", detail={"error": why})


def grade_submission(sub: Submission, kc: KeyContext | None, opts: GradeOptions, *,
                     rig: RigLookup | None = None) -> SubmissionResult:
    """Every rubric item of ``sub`` (with ``kc`` None only the items that need no lab data)."""
    env = CheckEnv(opts.rubric, kc, opts.convention, opts.reveal, opts.limits, _rig_lookup(opts, kc, rig if rig is not None else {}))
    done: dict[str, ItemResult] = {}
    for name in opts.rubric.order():
        if kc is None and needs_key(name):
            continue
        done[name] = _check(name, sub.answers.get(name), env, done)
    notes = list(sub.notes)
    if kc is None:
        skipped = [n for n in opts.rubric.items if needs_key(n)]
        if skipped:
            notes.append(f"not checked without lab data: {', '.join(skipped)}")
    elif kc.source == "group data":
        notes.append("graded against the key computed from your group's own data")
    items = tuple(done[n] for n in opts.rubric.items if n in done)
    return SubmissionResult(sub.submission_id, str(sub.source), sub.students, items, notes=tuple(notes))


def invalid_submission(submission_id: str, source: str, error: str, rubric: Rubric,
                       students: tuple[Student, ...] = ()) -> SubmissionResult:
    """A submission that could not be read: every item invalid, the reason as feedback."""
    items = tuple(ItemResult(item=n, status="invalid", points=0.0, max_points=i.points,
                             feedback=f"{fb.name(n)}: not graded: the submission could not be read ({error}).",
                             detail={"error": error}) for n, i in rubric.items.items())
    return SubmissionResult(submission_id, source, students, items, valid=False, error=error)
