"""The survey chart keeps one statement order in every lab's panel, so a statement compares across labs."""

from __future__ import annotations

from pathlib import Path

from grader.assess import build_survey_report, load_mapping, read_survey
from grader.assess.plots import likert_figure, statement_order

FIXTURES = Path(__file__).resolve().parents[2] / "submissions_fixtures" / "assessment"


def test_every_lab_panel_lists_the_statements_in_the_same_order() -> None:
    mapping = load_mapping()
    report = build_survey_report(read_survey(FIXTURES / "survey_qualtrics.csv", mapping), mapping)
    fig = likert_figure(report)
    lab_axes = fig.axes[:len(report.labs)]
    orders = [[t.get_text() for t in ax.get_yticklabels()] for ax in lab_axes]
    assert len(orders) >= 2 and all(order == orders[0] for order in orders)
    # the labs disagree on their own rankings, so a per-lab sort would have broken this
    own = [sorted((i for i in report.items if i.lab == lab.lab), key=lambda i: i.pct_agree or 0.0) for lab in report.labs]
    assert len({tuple(i.statement for i in ranking) for ranking in own}) > 1


def test_statement_order_pools_agreement_over_labs() -> None:
    mapping = load_mapping()
    report = build_survey_report(read_survey(FIXTURES / "survey_qualtrics.csv", mapping), mapping)
    order = statement_order(report.items)
    pooled = {s: sum((i.pct_agree or 0.0) * i.n for i in report.items if i.statement == s)
              / sum(i.n for i in report.items if i.statement == s) for s in order}
    assert [pooled[s] for s in order] == sorted(pooled[s] for s in order)
    assert set(order) == {i.statement for i in report.items}
