"""The report.json schemas (pydantic); ``report.json`` is ``model_dump_json`` of these.

Floats are rounded to 6 significant digits on output, so the same input always
gives a byte-identical file; NaN and infinities become ``null``.
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, PlainSerializer


def round6(value: float | None) -> float | None:
    """``value`` to 6 significant digits as report.json and report.xlsx give it (None where not finite): their
    last digits can differ between CPUs' BLAS kernels (an exam regression's t statistic did)."""
    if value is None or not math.isfinite(value):
        return None
    return float(f"{value:.6g}")


Num = Annotated[float | None, PlainSerializer(round6, return_type=float | None)]
Interval = tuple[Num, Num] | None
SCHEMA_VERSION = 1


class _Model(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


# ---------------------------------------------------------------- survey


class ScaleInfo(_Model):
    points: int
    labels: list[str]
    disagree: list[int]
    neutral: list[int]
    agree: list[int]


class LabInfo(_Model):
    lab: str
    lab_name: str
    did_yes: int
    did_no: int
    did_blank: int
    ratings_discarded: int


class RatingStats(_Model):
    statement: str
    statement_label: str
    n: int
    n_missing: int
    counts: list[int]
    pct_disagree: Num
    pct_neutral: Num
    pct_agree: Num
    median: Num
    q1: Num
    q3: Num
    iqr: Num
    mean: Num
    sd: Num
    mean_ci: Interval


class Item(RatingStats):
    lab: str
    lab_name: str
    n_not_done: int


class Alpha(_Model):
    lab: str
    lab_name: str
    value: Num
    n: int
    k: int
    ci: Interval


class PairTest(_Model):
    a: str
    b: str
    n: int
    v: Num
    p: Num
    p_holm: Num
    mean_diff: Num


class LabMean(_Model):
    lab: str
    n: int
    mean: Num


class Comparison(_Model):
    statement: str
    statement_label: str
    n_complete: int
    friedman_chi2: Num
    friedman_df: int | None
    friedman_p: Num
    kendall_w: Num
    means: list[LabMean]
    pairs: list[PairTest]
    highest: str | None
    supported: bool
    conclusion: str


class HoursBin(_Model):
    label: str
    count: int


class Hours(_Model):
    n: int
    n_missing: int
    mean: Num
    sd: Num
    median: Num
    q1: Num
    q3: Num
    min: Num
    max: Num
    bins: list[HoursBin]


class Mention(_Model):
    lab: str
    lab_name: str
    count: int
    pct: Num


class Quote(_Model):
    labs: list[str]
    text: str
    count: int


class MostUseful(_Model):
    n_answers: int
    n_blank: int
    no_lab_named: int
    tally: list[Mention]
    quotes: list[Quote]


class SurveyReport(_Model):
    kind: Literal["survey"] = "survey"
    schema_version: int = SCHEMA_VERSION
    form: str
    respondents: int
    scale: ScaleInfo
    labs: list[LabInfo]
    items: list[Item]
    overall: list[RatingStats]
    alpha: list[Alpha]
    comparisons: list[Comparison]
    hours: Hours | None
    most_useful: MostUseful | None
    notes: list[str]
    limitations: list[str]


# ---------------------------------------------------------------- exam


class GroupStats(_Model):
    group: str
    n: int
    mean: Num
    sd: Num
    median: Num
    rest_mean: Num


class ProblemReport(_Model):
    problem: str
    n: int
    item_max: Num
    groups: list[GroupStats]
    mean_diff: Num
    welch_t: Num
    welch_df: Num
    welch_p: Num
    welch_ci: Interval
    mannwhitney_u: Num
    mannwhitney_p: Num
    hedges_g: Num
    hedges_g_ci: Interval
    ancova_group_diff: Num
    ancova_group_ci: Interval
    ancova_group_p: Num
    balance_diff: Num
    balance_p: Num
    difficulty: Num
    item_rest_r: Num
    upper_lower_d: Num
    mde_80: Num
    n_needed_d05: int | None
    n_needed_d05_ancova: int | None
    n_needed_observed: int | None
    verdict: str


class ExamReport(_Model):
    kind: Literal["exam"] = "exam"
    schema_version: int = SCHEMA_VERSION
    unit: str
    treated: str
    control: str
    students: int
    problems: list[ProblemReport]
    why_uninformative: list[str]
    next_study: list[str]
    notes: list[str]
