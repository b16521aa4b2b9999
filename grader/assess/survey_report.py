"""Build the survey report (every figure of report.json) from parsed responses."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from grader.assess import stats
from grader.assess.claims import highest_claim
from grader.assess.free_text import most_useful
from grader.assess.mapping import SurveyMapping
from grader.assess.schemas import (
    Alpha,
    Comparison,
    Hours,
    HoursBin,
    Item,
    LabInfo,
    LabMean,
    PairTest,
    RatingStats,
    ScaleInfo,
    SurveyReport,
)
from grader.assess.survey_io import SurveyData

HOURS_TOP_BIN = 10


def _array(values: Sequence[float | None]) -> np.ndarray:
    return np.array([np.nan if v is None else v for v in values], dtype=float)


def build_survey_report(data: SurveyData, mapping: SurveyMapping) -> SurveyReport:
    """Every summary, test and sentence of the survey report."""
    alphas = _alphas(data, mapping)
    return SurveyReport(
        form=data.form,
        respondents=data.respondents,
        scale=_scale_info(mapping),
        labs=_lab_info(data, mapping),
        items=_items(data, mapping),
        overall=[
            _rating_stats(_array(data.overall[o.id]), mapping, o.id, o.label, data.respondents)
            for o in mapping.overall
        ],
        alpha=alphas,
        comparisons=[_comparison(data, mapping, s.id) for s in mapping.statements],
        hours=None if data.hours is None else _hours(_array(data.hours)),
        most_useful=None if data.most_useful is None else most_useful(data.most_useful, mapping.labs),
        notes=_notes(data, mapping) + _alpha_notes(alphas),
        limitations=_limitations(data, mapping),
    )


def _scale_info(mapping: SurveyMapping) -> ScaleInfo:
    scale = mapping.scale
    values = range(1, scale.points + 1)
    return ScaleInfo(
        points=scale.points,
        labels=list(scale.labels),
        disagree=[v for v in values if v < scale.midpoint],
        neutral=[v for v in values if v == scale.midpoint],
        agree=[v for v in values if v > scale.midpoint],
    )


def _lab_info(data: SurveyData, mapping: SurveyMapping) -> list[LabInfo]:
    out = []
    for lab in mapping.labs:
        flags = data.did_lab.get(lab.id, (None,) * data.respondents)
        out.append(
            LabInfo(
                lab=lab.id,
                lab_name=lab.name,
                did_yes=sum(f is True for f in flags),
                did_no=sum(f is False for f in flags),
                did_blank=sum(f is None for f in flags),
                ratings_discarded=data.discarded.get(lab.id, 0),
            )
        )
    return out


def _rating_stats(
    values: np.ndarray, mapping: SurveyMapping, statement: str, label: str, respondents: int, not_done: int = 0
) -> RatingStats:
    s = stats.likert_summary(values, mapping.scale.points)
    return RatingStats(
        statement=statement,
        statement_label=label,
        n=s.n,
        n_missing=respondents - s.n - not_done,
        counts=list(s.counts),
        pct_disagree=s.pct_disagree,
        pct_neutral=s.pct_neutral,
        pct_agree=s.pct_agree,
        median=s.median,
        q1=s.q1,
        q3=s.q3,
        iqr=None if s.q1 is None or s.q3 is None else s.q3 - s.q1,
        mean=s.mean,
        sd=s.sd,
        mean_ci=s.mean_ci,
    )


def _items(data: SurveyData, mapping: SurveyMapping) -> list[Item]:
    out = []
    for lab in mapping.labs:
        not_done = sum(f is False for f in data.did_lab.get(lab.id, ()))
        for st in mapping.statements:
            values = _array(data.ratings[(lab.id, st.id)])
            base = _rating_stats(values, mapping, st.id, st.label, data.respondents, not_done)
            out.append(Item(lab=lab.id, lab_name=lab.name, n_not_done=not_done, **base.model_dump()))
    return out


def _alphas(data: SurveyData, mapping: SurveyMapping) -> list[Alpha]:
    out = []
    for lab in mapping.labs:
        matrix = np.column_stack([_array(data.ratings[(lab.id, s.id)]) for s in mapping.statements])
        complete = stats.complete_rows(matrix)
        n, k = complete.shape
        value = stats.cronbach_alpha(complete)
        ci = None if value is None else stats.feldt_ci(value, n, k)
        out.append(Alpha(lab=lab.id, lab_name=lab.name, value=value, n=n, k=k, ci=ci))
    return out


def _alpha_notes(alphas: list[Alpha]) -> list[str]:
    """A note for each lab whose Cronbach's alpha is below 0: its statements' ratings vary against each other, as
    a reverse-worded statement makes them (the mapping has no reverse scoring: reword it, or recode its answers)."""
    return [f"Cronbach's alpha for {a.lab_name} is {a.value:.2f}, below 0: its statements' ratings vary against each "
            "other, as a reverse-worded statement makes them; every statement is read with higher as better, so recode "
            "a reverse-worded one (scale points + 1 − rating) before reading its figures"
            for a in alphas if a.value is not None and a.value < 0]


def _comparison(data: SurveyData, mapping: SurveyMapping, statement: str) -> Comparison:
    columns = {lab.id: _array(data.ratings[(lab.id, statement)]) for lab in mapping.labs}
    friedman = stats.friedman(np.column_stack(list(columns.values())))
    pairs = stats.pairwise_wilcoxon(columns)
    means = {lab: (float(np.nanmean(v)) if np.any(~np.isnan(v)) else None) for lab, v in columns.items()}
    label = mapping.statement(statement).label
    names = {lab.id: lab.name for lab in mapping.labs}
    highest, supported, sentence = highest_claim(label, means, friedman, pairs, names)
    return Comparison(
        statement=statement,
        statement_label=label,
        n_complete=int(stats.complete_rows(np.column_stack(list(columns.values()))).shape[0]),
        friedman_chi2=None if friedman is None else friedman.chi2,
        friedman_df=None if friedman is None else friedman.df,
        friedman_p=None if friedman is None else friedman.p,
        kendall_w=None if friedman is None else friedman.kendall_w,
        means=[LabMean(lab=lab, n=int(np.sum(~np.isnan(v))), mean=means[lab]) for lab, v in columns.items()],
        pairs=[
            PairTest(a=p.a, b=p.b, n=p.n, v=p.statistic, p=p.p, p_holm=p.p_holm, mean_diff=p.mean_diff)
            for p in pairs
        ],
        highest=highest,
        supported=supported,
        conclusion=sentence,
    )


def _hours(values: np.ndarray) -> Hours:
    x = values[~np.isnan(values)]
    if x.size == 0:
        return Hours(n=0, n_missing=int(values.size), mean=None, sd=None, median=None, q1=None,
                     q3=None, min=None, max=None, bins=[])
    top = min(HOURS_TOP_BIN, math.floor(x.max()) + 1)
    bins = [HoursBin(label=f"{lo} to <{lo + 1} h", count=int(np.sum((x >= lo) & (x < lo + 1)))) for lo in range(top)]
    if x.max() >= HOURS_TOP_BIN:
        bins.append(HoursBin(label=f"{HOURS_TOP_BIN}+ h", count=int(np.sum(x >= HOURS_TOP_BIN))))
    q1, median, q3 = (float(q) for q in np.percentile(x, [25, 50, 75]))
    return Hours(
        n=int(x.size),
        n_missing=int(values.size - x.size),
        mean=float(x.mean()),
        sd=float(x.std(ddof=1)) if x.size > 1 else None,
        median=median,
        q1=q1,
        q3=q3,
        min=float(x.min()),
        max=float(x.max()),
        bins=bins,
    )


def _notes(data: SurveyData, mapping: SurveyMapping) -> list[str]:
    notes = list(data.notes)
    for lab in mapping.labs:
        dropped = data.discarded.get(lab.id, 0)
        if dropped:
            notes.append(
                f"{dropped} {lab.name} ratings were left out because the student answered "
                f'"No" to having done the lab.'
            )
    return notes


def _limitations(data: SurveyData, mapping: SurveyMapping) -> list[str]:
    k = len(mapping.labs)
    return [
        f"These are self-reported perceptions of one cohort ({data.respondents} respondents): they show "
        "how students rated the labs, not what they learned.",
        "There is no comparison group: without survey data for the lab this one replaced, the survey "
        "cannot show that the new lab is better than the old one.",
        "All labs were rated on one form, after they were done: when a lab came in the course "
        "(order, recency) cannot be separated from the lab itself.",
        "Ratings are ordinal. Means and SDs are given because the paper reports means, but the "
        "percentages and medians are the safer summaries, and all tests are rank-based.",
        "Missing answers (did not do the lab, blank, N/A) are left out and never counted as neutral; "
        "every figure gives its n. The Friedman test uses only students who rated all "
        f"{k} labs on the statement; each Wilcoxon test uses the students who rated both labs.",
        f"The Holm correction is applied to the {k * (k - 1) // 2} pairwise tests of each statement, "
        "not across statements.",
    ]
