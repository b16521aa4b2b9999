"""Build the exam-question report: group comparisons per problem and overall, and power.

Scores are analysed as a percentage of their maximum, so problems with
different maxima can be pooled; the rest-of-test score (total − item) is a
percentage of (test max − item max). The "overall" entry pools both problems
and adds the problem as a factor in the ANCOVA.
"""

from __future__ import annotations

import math

import pandas as pd

from grader.assess import exam_stats as es
from grader.assess.claims import fmt_p
from grader.assess.exam_io import CONTROL, RESERVED_PROBLEM, TREATED, ExamData
from grader.assess.schemas import ExamReport, GroupStats, ProblemReport

OVERALL = RESERVED_PROBLEM
MEDIUM_D = 0.5


def exam_frame(data: ExamData) -> pd.DataFrame:
    """One row per student: score and rest as % of maximum, group and problem."""
    return pd.DataFrame(
        {
            "score": 100 * data.item_score / data.item_max,
            "rest": 100 * (data.total_score - data.item_score) / (data.total_max - data.item_max),
            "group": list(data.group),
            "problem": list(data.problem),
            "item_max": data.item_max,
        }
    )


def build_exam_report(data: ExamData) -> ExamReport:
    """Every figure and sentence of the exam report."""
    frame = exam_frame(data)
    names = list(dict.fromkeys(data.problem))
    problems = [_problem(name, frame[frame["problem"] == name]) for name in names]
    if len(names) > 1:
        problems.append(_problem(OVERALL, frame))
    return ExamReport(
        unit="percent of the maximum score",
        treated=TREATED,
        control=CONTROL,
        students=len(frame),
        problems=problems,
        why_uninformative=_why(problems, len(frame)),
        next_study=_next_study(problems, len(frame), len(names)),
        notes=[
            "Differences are with_lab_reference minus without_lab_reference; negative means the "
            "lab reference group scored lower.",
            "Discrimination uses the rest-of-test score (total minus the item), so the item is not "
            "correlated with itself; the upper-lower index compares the top and bottom 27 % on it.",
            'The "overall" entry pools both problems; its ANCOVA adds the problem as a factor.',
        ],
    )


def informative_heading(report: ExamReport) -> str:
    """The paper's verdict as a heading when the design was underpowered, else a neutral one."""
    underpowered = any(p.mde_80 is None or p.mde_80 > MEDIUM_D for p in report.problems if p.problem != OVERALL)
    return "Why this assessment proved less informative" if underpowered else "How informative this comparison is"


def _group(frame: pd.DataFrame, group: str) -> GroupStats:
    sub = frame[frame["group"] == group]
    n = len(sub)
    return GroupStats(
        group=group,
        n=n,
        mean=float(sub["score"].mean()) if n else None,
        sd=float(sub["score"].std(ddof=1)) if n > 1 else None,
        median=float(sub["score"].median()) if n else None,
        rest_mean=float(sub["rest"].mean()) if n else None,
    )


def _problem(name: str, frame: pd.DataFrame) -> ProblemReport:
    a = frame.loc[frame["group"] == TREATED, "score"].to_numpy()
    b = frame.loc[frame["group"] == CONTROL, "score"].to_numpy()
    welch = es.welch(a, b)
    mw = es.mann_whitney(a, b)
    g = es.hedges_g(a, b)
    ancova = es.ancova(frame, TREATED, CONTROL)
    balance = es.welch(frame.loc[frame["group"] == TREATED, "rest"].to_numpy(),
                       frame.loc[frame["group"] == CONTROL, "rest"].to_numpy())
    r = es.item_rest_r(frame["score"].to_numpy(), frame["rest"].to_numpy())
    needed = es.n_per_group(MEDIUM_D)
    report = ProblemReport(
        verdict="",
        problem=name,
        n=len(frame),
        item_max=float(frame["item_max"].iloc[0]) if frame["item_max"].nunique() == 1 else None,
        groups=[_group(frame, TREATED), _group(frame, CONTROL)],
        mean_diff=None if welch is None else welch.diff,
        welch_t=None if welch is None else welch.t,
        welch_df=None if welch is None else welch.df,
        welch_p=None if welch is None else welch.p,
        welch_ci=None if welch is None else welch.ci,
        mannwhitney_u=None if mw is None else mw[0],
        mannwhitney_p=None if mw is None else mw[1],
        hedges_g=None if g is None else g[0],
        hedges_g_ci=None if g is None else g[1],
        ancova_group_diff=None if ancova is None else ancova.diff,
        ancova_group_ci=None if ancova is None else ancova.ci,
        ancova_group_p=None if ancova is None else ancova.p,
        balance_diff=None if balance is None else balance.diff,
        balance_p=None if balance is None else balance.p,
        difficulty=float(frame["score"].mean() / 100),
        item_rest_r=r,
        upper_lower_d=es.upper_lower_index(frame["score"].to_numpy(), frame["rest"].to_numpy(), 100.0),
        mde_80=es.minimum_detectable_d(len(a), len(b)),
        n_needed_d05=needed,
        n_needed_d05_ancova=None if r is None or needed is None else math.ceil(needed * (1 - r * r)),
        n_needed_observed=None if g is None else es.n_per_group(g[0]),
    )
    return report.model_copy(update={"verdict": _verdict(report)})


def _points(diff: float) -> str:
    return f"{abs(diff):.1f} percentage points {'lower' if diff < 0 else 'higher'}"


def _verdict(p: ProblemReport) -> str:
    """One honest paragraph on what this comparison can and cannot show."""
    treated, control = p.groups
    if p.welch_p is None or p.hedges_g is None or p.hedges_g_ci is None:
        if min(treated.n, control.n) >= 2 and treated.sd == 0 and control.sd == 0:
            return (f"{p.problem}: within each group every student scored the same "
                    f"({treated.mean:.1f} % and {control.mean:.1f} %, n = {treated.n} and {control.n}); "
                    "with no spread there is nothing to test.")
        return f"{p.problem}: too few students in a group (n = {treated.n} and {control.n}) to compare."
    low, high = p.hedges_g_ci
    text = (
        f"{p.problem}: the lab-reference group scored {_points(p.mean_diff or 0.0)} "
        f"({treated.mean:.1f} % vs {control.mean:.1f} %, n = {treated.n} and {control.n}); "
        f"Welch t({p.welch_df:.1f}) = {p.welch_t:.2f}, {fmt_p(p.welch_p)}; "
        f"Mann-Whitney {fmt_p(p.mannwhitney_p)}. Hedges' g = {p.hedges_g:.2f} (95 % CI {low:.2f} to {high:.2f})."
    )
    if p.ancova_group_p is not None:
        text += f" Adjusted for the rest of the test: {_points(p.ancova_group_diff or 0.0)}, {fmt_p(p.ancova_group_p)}."
    else:
        text += " Too few students to adjust for the rest of the test (limitation: no ANCOVA)."
    if p.balance_p is not None and p.balance_p < 0.05:
        text += (
            f" The groups differed on the rest of the test ({fmt_p(p.balance_p)}), so the unadjusted "
            "difference mixes the lab reference with ability; the adjusted figure is the fairer one."
        )
    text += f" With these group sizes only |d| ≥ {p.mde_80:.2f} had an 80 % chance of detection"
    if p.welch_p < 0.05:
        return text + "; the unadjusted difference is statistically significant."
    return text + (
        f", so the non-significant result cannot tell no effect from anything between "
        f"g = {low:.2f} (the reference hurts) and g = {high:.2f} (it helps)."
    )


def _per_problem(problems: list[ProblemReport]) -> list[ProblemReport]:
    singles = [p for p in problems if p.problem != OVERALL]
    return singles or problems


def _power_sentence(singles: list[ProblemReport], pooled: ProblemReport) -> str:
    sized = [p for p in singles if p.mde_80 is not None]
    sizes = ", ".join(f"{p.problem} {p.groups[0].n} vs {p.groups[1].n}" for p in singles)
    if not sized:
        return f"Too few students in a group to compare at all ({sizes})."
    mdes = ", ".join(f"{p.mde_80:.2f}" for p in sized)
    pooled_text = ""
    if pooled.mde_80 is not None and pooled is not singles[0]:
        pooled_text = f" (pooled over problems: {pooled.mde_80:.2f})"
    if all((p.mde_80 or 0.0) <= MEDIUM_D for p in sized):
        return f"The groups ({sizes}) were large enough to detect a medium effect: |d| ≥ {mdes}{pooled_text}."
    return (
        f"Too few students per group ({sizes}): at α = 0.05 and 80 % power the comparisons could only "
        f"detect effects of |d| ≥ {mdes}{pooled_text}, larger than a one-sentence reference to a lab is "
        "likely to produce."
    )


def _why(problems: list[ProblemReport], students: int) -> list[str]:
    singles = _per_problem(problems)
    pooled = next((p for p in problems if p.problem == OVERALL), singles[0])
    out = [_power_sentence(singles, pooled)]
    for p in singles:
        if p.hedges_g is not None and p.mde_80 is not None and abs(p.hedges_g) < p.mde_80:
            need = ""
            if p.n_needed_observed:
                need = f"; detecting an effect that size needs about {p.n_needed_observed} students per group"
            out.append(f"{p.problem}: the observed g = {p.hedges_g:.2f} is below what the design could detect{need}.")
    for p in singles:
        if p.difficulty is not None and p.item_rest_r is not None:
            ceiling = " - near the ceiling, which hides differences" if p.difficulty > 0.8 else ""
            out.append(
                f"{p.problem} is a single item (difficulty {p.difficulty:.2f}{ceiling}; item-rest r = "
                f"{p.item_rest_r:.2f}): one question is a noisy measure of learning."
            )
    out.append(
        f"Splitting {students} students into {2 * len(singles)} groups ({len(singles)} problem(s) × two "
        "versions) leaves every comparison carrying all between-student differences, which a within-student "
        "design would remove."
    )
    return out


def _next_study(problems: list[ProblemReport], students: int, n_problems: int) -> list[str]:
    singles = _per_problem(problems)
    needed = singles[0].n_needed_d05 or 0
    per_offering = students / max(n_problems, 1)
    out = [
        f"To detect a medium effect (d = {MEDIUM_D}) with 80 % power at α = 0.05 needs {needed} students "
        f"per group, {2 * needed} per problem: about {math.ceil(2 * needed / per_offering)} offerings of a "
        f"{students}-student class with {n_problems} problem(s), or {math.ceil(2 * needed / students)} if "
        "every student gets the same problem.",
    ]
    ancova = [p.n_needed_d05_ancova for p in singles if p.n_needed_d05_ancova is not None]
    if ancova:
        out.append(
            f"Adjusting for the rest-of-test score (ANCOVA) lowers this to about {min(ancova)}-{max(ancova)} "
            "per group, as far as the item correlates with the rest of the test."
        )
    out.append(
        "Better: give every student both problems, one with and one without the lab reference "
        "(counterbalanced), and compare within students; and measure each outcome with several "
        "items rather than one."
    )
    return out
