"""Reports as titled tables, shared by the HTML and XLSX renderers.

A :class:`View` holds raw values and a kind per column; each renderer formats
them its own way (text in HTML, typed cells with number formats in XLSX).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

from grader.assess.schemas import ExamReport, SurveyReport

Kind = Literal["text", "int", "pct", "num", "p"]
Value = str | int | float | None


@dataclass(frozen=True)
class View:
    title: str
    headers: tuple[str, ...]
    kinds: tuple[Kind, ...]
    rows: tuple[tuple[Value, ...], ...]


def _view(title: str, columns: Sequence[tuple[str, Kind]], rows: Sequence[tuple[Value, ...]]) -> View:
    return View(title, tuple(h for h, _ in columns), tuple(k for _, k in columns), tuple(rows))


def _ci(ci: tuple[float | None, float | None] | None) -> tuple[float | None, float | None]:
    return (None, None) if ci is None else ci


_STATS: list[tuple[str, Kind]] = [
    ("% disagree", "pct"), ("% neutral", "pct"), ("% agree", "pct"),
    ("median", "num"), ("Q1", "num"), ("Q3", "num"), ("mean", "num"), ("SD", "num"),
    ("mean 95% CI low", "num"), ("mean 95% CI high", "num"),
]


def survey_summary(report: SurveyReport) -> list[View]:
    """Per lab × statement figures, the overall statements and Cronbach's alpha."""
    items = [
        (i.lab_name, i.statement_label, i.n, i.n_not_done, i.n_missing, i.pct_disagree, i.pct_neutral,
         i.pct_agree, i.median, i.q1, i.q3, i.mean, i.sd, *_ci(i.mean_ci))
        for i in report.items
    ]
    overall = [
        (o.statement_label, o.n, o.n_missing, o.pct_disagree, o.pct_neutral, o.pct_agree, o.median,
         o.q1, o.q3, o.mean, o.sd, *_ci(o.mean_ci))
        for o in report.overall
    ]
    alpha = [(a.lab_name, a.value, a.n, a.k, *_ci(a.ci)) for a in report.alpha]
    views = [_view(
        "Ratings by lab and statement",
        [("lab", "text"), ("statement", "text"), ("n", "int"), ("did not do lab", "int"), ("blank or N/A", "int"),
         *_STATS],
        items,
    )]
    if overall:
        views.append(_view(
            "Overall statements", [("statement", "text"), ("n", "int"), ("blank or N/A", "int"), *_STATS], overall
        ))
    views.append(_view(
        "Internal consistency of each lab's statements (Cronbach's alpha, Feldt 95% CI; complete cases)",
        [("lab", "text"), ("alpha", "num"), ("n complete", "int"), ("items", "int"),
         ("95% CI low", "num"), ("95% CI high", "num")],
        alpha,
    ))
    return views


def survey_comparisons(report: SurveyReport) -> list[View]:
    """Friedman/Kendall's W per statement and the Holm-corrected pairwise tests."""
    names = {lab.lab: lab.lab_name for lab in report.labs}
    omnibus = [
        (c.statement_label, c.n_complete, c.friedman_chi2, c.friedman_df, c.friedman_p, c.kendall_w,
         names.get(c.highest or "", ""), "yes" if c.supported else "no")
        for c in report.comparisons
    ]
    pairs = [
        (c.statement_label, names[p.a], names[p.b], p.n, p.mean_diff, p.v, p.p, p.p_holm)
        for c in report.comparisons
        for p in c.pairs
    ]
    return [
        _view("Across labs, within students (Friedman test on students who rated every lab)",
              [("statement", "text"), ("n complete", "int"), ("chi2", "num"), ("df", "int"), ("p", "p"),
               ("Kendall's W", "num"), ("highest mean", "text"), ("claim supported", "text")], omnibus),
        _view("Pairwise Wilcoxon signed-rank tests (Holm-corrected within each statement)",
              [("statement", "text"), ("lab A", "text"), ("lab B", "text"), ("n paired", "int"),
               ("mean A - B", "num"), ("V", "num"), ("p", "p"), ("p Holm", "p")], pairs),
    ]


def survey_hours(report: SurveyReport) -> list[View]:
    h = report.hours
    if h is None:
        return []
    summary = [("n", h.n), ("missing", h.n_missing), ("mean", h.mean), ("SD", h.sd), ("median", h.median),
               ("Q1", h.q1), ("Q3", h.q3), ("min", h.min), ("max", h.max)]
    return [
        _view("Hours per week outside lab", [("statistic", "text"), ("value", "num")], summary),
        _view("Distribution", [("hours", "text"), ("students", "int")], [(b.label, b.count) for b in h.bins]),
    ]


def survey_most_useful(report: SurveyReport) -> list[View]:
    m = report.most_useful
    if m is None:
        return []
    names = {lab.lab: lab.lab_name for lab in report.labs}
    tally = [(t.lab_name, t.count, t.pct) for t in m.tally] + [("no lab named", m.no_lab_named, None)]
    quotes = [(", ".join(names[q] for q in quote.labs) or "-", quote.text, quote.count) for quote in m.quotes]
    return [
        _view(f"Most useful lab: labs named in {m.n_answers} answers ({m.n_blank} blank)",
              [("lab", "text"), ("answers naming it", "int"), ("% of answers", "pct")], tally),
        _view("The answers (identical answers once, with their count)",
              [("labs named", "text"), ("answer", "text"), ("times given", "int")], quotes),
    ]


def exam_views(report: ExamReport) -> list[View]:
    """Group summaries, tests, item analysis and power, one row per problem."""
    groups = [
        (p.problem, g.group, g.n, g.mean, g.sd, g.median, g.rest_mean) for p in report.problems for g in p.groups
    ]
    tests = [
        (p.problem, p.mean_diff, *_ci(p.welch_ci), p.welch_t, p.welch_df, p.welch_p, p.mannwhitney_u,
         p.mannwhitney_p, p.hedges_g, *_ci(p.hedges_g_ci), p.ancova_group_diff, p.ancova_group_p, p.balance_p)
        for p in report.problems
    ]
    items = [(p.problem, p.difficulty, p.item_rest_r, p.upper_lower_d) for p in report.problems]
    power = [
        (p.problem, p.mde_80, p.n_needed_d05, p.n_needed_d05_ancova, p.n_needed_observed) for p in report.problems
    ]
    return [
        _view("Item score by group (% of maximum)",
              [("problem", "text"), ("group", "text"), ("n", "int"), ("mean", "num"), ("SD", "num"),
               ("median", "num"), ("rest-of-test mean", "num")], groups),
        _view("Group comparison (with minus without lab reference)",
              [("problem", "text"), ("difference", "num"), ("95% CI low", "num"), ("95% CI high", "num"),
               ("Welch t", "num"), ("df", "num"), ("Welch p", "p"), ("Mann-Whitney U", "num"),
               ("Mann-Whitney p", "p"), ("Hedges' g", "num"), ("g CI low", "num"), ("g CI high", "num"),
               ("ANCOVA difference", "num"), ("ANCOVA p", "p"), ("balance p (rest of test)", "p")], tests),
        _view("Item analysis (difficulty = mean proportion of the maximum)",
              [("problem", "text"), ("difficulty", "num"), ("item-rest r", "num"), ("upper-lower 27% D", "num")],
              items),
        _view("Power (two-sided alpha = 0.05, 80% power)",
              [("problem", "text"), ("minimum detectable d", "num"), ("n per group for d = 0.5", "int"),
               ("... with ANCOVA", "int"), ("n per group for the observed g", "int")], power),
    ]
