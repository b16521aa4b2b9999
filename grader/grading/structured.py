"""Checking the structured items: closed-loop pole sets per gain, and PD/PI designs."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from grader.grading import ecf
from grader.grading import feedback as fb
from grader.grading.answers import AnswerError, Gains, gain_units, is_blank, read_design, read_poles
from grader.grading.checks import CheckEnv, best, mistake_text, result
from grader.grading.designs import ModelVerdict, evaluate_design
from grader.grading.mistakes import wrong_value
from grader.grading.results import READ_STATUSES, ItemResult
from grader.grading.rubric import RubricItem
from grader.grading.unreachable import says_not_reachable
from grader.grading.units_diagnosis import slip_candidates
from grader.units import quantity_to_float

PoleRuns = list[tuple[Gains, list[complex]]]


def key_runs(value: list[dict[str, Any]]) -> PoleRuns:
    """The key's pole sets, one per distinct set of gains (runs repeat gains)."""
    out: PoleRuns = []
    for run in value:
        g = Gains(float(run["Kp"]), float(run["Ki"]), float(run["Kd"]))
        if not any(g.matches(h) for h, _ in out):
            out.append((g, [complex(re, im) for re, im in run["poles"]]))
    return out


def same_set(given: list[complex], ref: list[complex], rel: float, absolute: float) -> bool:
    """Equal as sets: an optimal one-to-one matching with every pole within tolerance."""
    from scipy.optimize import linear_sum_assignment  # only when poles are graded

    if len(given) != len(ref):
        return False
    cost = np.abs(np.subtract.outer(np.asarray(given), np.asarray(ref)))
    rows, cols = linear_sum_assignment(cost)
    return all(cost[i, j] <= rel * abs(ref[j]) + absolute for i, j in zip(rows, cols))


def _score(answer: PoleRuns, ref: PoleRuns, rel: float, absolute: float) -> list[tuple[str, bool]]:
    """The gains (as text) whose pole sets are wrong, each with whether the student gave poles there. Runs repeat
    gains, so a student may give a gain's poles more than once: every set given there must be right."""
    bad = []
    for g, poles in ref:
        mine = [p for h, p in answer if h.matches(g)]
        if not mine or not all(same_set(m, poles, rel, absolute) for m in mine):
            bad.append((_gain_text(g), bool(mine)))
    return bad


def _wrong_text(bad: list[tuple[str, bool]], reveal: bool) -> str:
    """Where the poles are wrong; without ``reveal`` the lab's gains the student left out are only counted."""
    given = [g for g, mine in bad if mine]
    absent = [g for g, mine in bad if not mine]
    parts = [f"wrong at {'; '.join(given)}"] if given else []
    if absent:
        parts.append(f"no poles given at {'; '.join(absent)}" if reveal else
                     f"no poles given at {len(absent)} of the lab's gains (give them for every run's gains)")
    return ", and ".join(parts)


def _gain_text(g: Gains) -> str:
    return "Kp = " + f"{g.Kp:g}" + (f", Ki = {g.Ki:g}" if g.Ki else "") + (f", Kd = {g.Kd:g}" if g.Kd else "")


def check_poles(name: str, raw: Any, env: CheckEnv, done: Mapping[str, ItemResult]) -> ItemResult:
    item = env.rubric.items[name]
    if is_blank(raw):
        return result(name, item, "missing", 0.0, fb.missing(name))
    assert env.kc is not None
    kname = env.rubric.key_name(name)
    entry = env.kc.key.quantities[kname]
    if not entry.reachable:  # the key has no poles (e.g. the data give no model)
        if says_not_reachable(raw):
            return result(name, item, "correct", 1.0, fb.correct(name, entry.status.replace("_", " ")))
        return result(name, item, "incorrect", 0.0, fb.number_not_reachable(name, "these poles", entry.reason if env.reveal else None),
                      detail={"key_status": entry.status})
    try:
        answer = read_poles(raw, limits=env.limits)
    except AnswerError as exc:
        return result(name, item, "invalid", 0.0, fb.invalid(name, str(exc)), detail={"error": str(exc)})
    ref = key_runs(env.kc.value(kname))
    rel = item.tolerance.relative or 0.0
    absolute = float(item.tolerance.absolute or 0.0) if not isinstance(item.tolerance.absolute, str) else \
        quantity_to_float(item.tolerance.absolute, "1/s", where="tolerance.absolute")
    bad = _score(answer, ref, rel, absolute)
    stray = list(dict.fromkeys(_gain_text(g) for g, _ in answer if not any(g.matches(h) for h, _ in ref)))
    detail = {"wrong_gains": [g for g, _ in bad], "gains": len(ref), **({"unmatched_gains": stray} if stray else {})}
    aside = ("" if not stray else  # the lab's gains are named only with reveal (as _wrong_text does)
             f" Poles given at {'; '.join(stray)} match none of the lab's runs and were not graded." if env.reveal else
             f" Poles given at {len(stray)} gain(s) that none of the lab's runs used were not graded.")
    if not bad:
        return result(name, item, "correct", 1.0, f"{fb.name(name)}: correct at every gain.{aside}", detail=detail)
    all_ok = lambda runs: runs is not None and not _score(answer, key_runs(runs), rel, absolute)  # noqa: E731
    cands = []
    read = {d: done[d] for d in item.depends_on if d in done and done[d].status in READ_STATUSES}
    own = {d: r.value for d, r in read.items()}
    if any(r.status != "correct" for r in read.values()) and all_ok(ecf.recompute(kname, env.kc, own)):
        cands.append(result(name, item, "correct_ecf", item.ecf_credit, f"{fb.name(name)}: they differ from the key but follow "
                            "from your own model (error carried forward).", mistake="ecf", detail=detail))
    for m in item.mistakes:
        if all_ok(wrong_value(m.code, env.mistake_env, kname)):
            cands.append(result(name, item, "known_mistake", m.credit, f"{fb.name(name)}: {mistake_text(item, m.code)}",
                                mistake=m.code, detail=detail))
    for slip in slip_candidates("rad/s") if not cands else ():
        if not _score(answer, [(g, [p * slip.factor for p in ps]) for g, ps in ref], rel, absolute):
            cands.append(result(name, item, "unit_mismatch", item.unit_mismatch_credit, fb.unit_slip(name, slip, None, "1/s"),
                                mistake=f"unit_slip:{slip.used}->{slip.needed}",
                                detail={**detail, "unit_used": slip.used, "unit_expected": slip.needed, "factor": slip.factor}))
            break
    share = 1.0 - len(bad) / len(ref)
    right = f" (right at the other {len(ref) - len(bad)})" if share else ""
    text = f"{fb.name(name)}: {_wrong_text(bad, env.reveal)}{right}.{aside}"
    return best(cands, result(name, item, "incorrect", share, text, detail=detail))


GOALS = {"pd_design": ("cuts the step overshoot of P control alone", "does not cut the step overshoot of P control alone enough"),
         "pi_design": ("removes the ramp error P control alone leaves", "does not remove the ramp error P control alone leaves")}


def _design_text(name: str, m: ModelVerdict, rig: str | None, reveal: bool) -> list[str]:
    what = "overshoot" if name == "pd_design" else "ramp error"
    unit = "%" if name == "pd_design" else "in"
    num = (lambda x: f"{100 * x:.1f} %") if name == "pd_design" else (lambda x: f"{x:.4f} in")  # noqa: E731
    if not m.stable:
        return ["the loop is unstable with these gains on the model identified from your group's lab data."]
    out = ["the loop is stable on the model identified from your group's lab data"]
    met, unmet = GOALS[name]
    out.append(f"the design {met if m.goal_met else unmet}" +
               (f" ({what} {num(m.achieved)} vs {num(m.baseline)} with P alone)" if reveal else ""))
    if m.claim_ok is None:
        out.append(f"no {what} claimed (give it in {unit})")
    else:
        out.append(f"your claimed {what} {'matches' if m.claim_ok else 'does not match'} the simulation")
    if rig in ("limit_cycle", "unstable"):
        out.append("warning: on the rig simulator (friction, quantization) it would " +
                   ("limit-cycle (hunt) around the target" if rig == "limit_cycle" else "go unstable"))
    return out


def check_design(name: str, raw: Any, env: CheckEnv) -> ItemResult:
    item: RubricItem = env.rubric.items[name]
    if is_blank(raw):
        return result(name, item, "missing", 0.0, fb.missing(name))
    assert env.kc is not None and item.design is not None
    spec = item.design
    try:
        answer = read_design(raw, item=name, gain_unit=env.kc.unit("Kp_crit"))
    except AnswerError as exc:
        return result(name, item, "invalid", 0.0, fb.invalid(name, str(exc)), detail={"error": str(exc)})
    if not env.kc.key.identified:  # no model to check the design on
        why = f"cannot be checked: your station's data give no model ({env.kc.key.quantities['Kce'].reason})"
        return result(name, item, "invalid", 0.0, f"{fb.name(name)}: {why}.", detail={"error": why})
    ramp = env.kc.key.quantities.get("ramp_ess_P")
    rate = float(ramp.inputs.get("ramp rate [in/s]", 1.0)) if ramp else 1.0
    m = evaluate_design(name, answer, env.kc.params(), spec, ramp_rate=rate)
    rig = env.rig(name, answer.gains) if m.stable else None
    credit = (spec.stable_credit * m.stable + spec.goal_credit * m.goal_met + spec.claim_credit * bool(m.claim_ok))
    failures = [code for code, ok in (("unstable_on_model", m.stable), ("goal_not_met", m.goal_met),
                                      ("claim_mismatch", bool(m.claim_ok))) if not ok]
    if rig in ("limit_cycle", "unstable"):
        failures.append(f"rig_{rig}")
        credit = max(credit - spec.rig_penalty, 0.0)
    g = answer.gains
    units = gain_units(env.kc.unit("Kp_crit"))
    detail = {"Kp": g.Kp, "Ki": g.Ki, "Kd": g.Kd, "gain_units": units, "stable": m.stable, "goal_met": m.goal_met,
              "claim": answer.claim, "claim_ok": m.claim_ok, "achieved": _millionths(m.achieved),
              "baseline_P": _millionths(m.baseline), "rig": rig or "not checked"}
    status = "correct" if not failures or failures == [f"rig_{rig}"] and spec.rig_penalty == 0 else "incorrect"
    text = f"{fb.name(name)}: " + "; ".join(_design_text(name, m, rig, env.reveal)) + "."
    return result(name, item, status, credit, text, mistake=failures[0] if failures else None, detail=detail)


def _millionths(x: float) -> float | None:
    """A design's overshoot (fraction) or ramp error [in] as the report gives it: to a millionth, or None where
    infinite (an unstable loop). The ramp error a PI design leaves is a decaying remainder whose digits beyond that
    differ with the CPU's BLAS kernels (6.5726e-06 in under Prescott's, 6.5719e-06 under SkylakeX's)."""
    return round(float(x), 6) if math.isfinite(x) else None
