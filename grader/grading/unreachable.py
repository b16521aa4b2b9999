"""Answers about values a rig may not have: "not reachable" is an answer, not a blank.

A key item with ``status: not_reachable`` (e.g. ``Kp_25_overshoot`` of a lightly damped
rig that turns unstable before it overshoots 25 %) or ``not_identifiable`` (e.g. ``Kce`` from an
instability run that does not oscillate) is answered correctly by one of
:data:`NOT_REACHABLE_WORDS` (case-insensitive; ``-`` or ``_`` may stand for the space).
A number for such an item is incorrect, unless the student's own upstream values do give
that number (error carried forward); a not-reachable answer for an item the rig does have
is incorrect, unless the student's own upstream values make the item unreachable.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from typing import Any

from grader.grading import ecf
from grader.grading import feedback as fb
from grader.grading.checks import CheckEnv, result
from grader.grading.results import READ_STATUSES, ItemResult

#: the accepted ways to say "this value does not exist for the rig" (compared lower-cased)
NOT_REACHABLE_WORDS = ("not reachable", "unreachable", "none", "n/a", "na", "not identifiable", "unidentifiable")
_SEPARATORS = re.compile(r"[\s_\-]+")


def says_not_reachable(raw: Any) -> bool:
    """True when the answer is one of :data:`NOT_REACHABLE_WORDS` (case-insensitive)."""
    if not isinstance(raw, str) or len(raw) > 40:
        return False
    return _SEPARATORS.sub(" ", raw.strip().lower()) in NOT_REACHABLE_WORDS


def _own_upstream(name: str, env: CheckEnv, done: Mapping[str, ItemResult]) -> tuple[list[str], dict[str, Any]]:
    """The wrongly answered upstream items and the student's read upstream values."""
    read = {d: done[d] for d in env.rubric.items[name].depends_on if d in done and done[d].status in READ_STATUSES}
    return [d for d, r in read.items() if r.status != "correct"], {d: r.value for d, r in read.items()}


def check_not_reachable(name: str, raw: Any, env: CheckEnv, done: Mapping[str, ItemResult]) -> ItemResult | None:
    """The verdict on a quantity answer that says "not reachable"; None for any other answer
    (:func:`grader.grading.checks.check_quantity` grades numbers, also for not-reachable items)."""
    if env.kc is None or not says_not_reachable(raw):
        return None
    item = env.rubric.items[name]
    kname = env.rubric.key_name(name)
    entry = env.kc.key.quantities[kname]
    detail = {"key_status": entry.status, "answer": "not reachable"}
    if not entry.reachable:
        return result(name, item, "correct", 1.0, fb.correct(name, entry.status.replace("_", " ")), detail=detail)
    wrong, own = _own_upstream(name, env, done)
    target = ecf.recompute(kname, env.kc, own) if wrong else None
    if isinstance(target, float) and math.isnan(target):
        text = fb.ecf(name, "not reachable", wrong, None, "")
        return result(name, item, "correct_ecf", item.ecf_credit, text, mistake="ecf", detail={**detail, "from": wrong})
    return result(name, item, "incorrect", 0.0, _reachable_text(name, env, kname), detail=detail)


def _reachable_text(name: str, env: CheckEnv, kname: str) -> str:
    assert env.kc is not None
    if not env.reveal:
        return fb.reachable_after_all(name, None, "")
    unit = env.rubric.items[name].unit or env.kc.unit(kname)
    return fb.reachable_after_all(name, float(env.kc.value(kname)), unit)
