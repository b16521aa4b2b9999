"""Table-driven: every fixture in submissions_fixtures/grading gets the verdicts listed in
submissions_fixtures/grading_expected.json (written by its generator from first principles)."""

from __future__ import annotations

import pytest

from grader.grading.results import STATUSES, SubmissionResult

from .conftest import EXPECTED, FIXTURES


def test_every_fixture_is_listed() -> None:
    assert sorted(p.name for p in FIXTURES.iterdir()) == sorted(EXPECTED)


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_fixture_verdicts(name: str, graded: dict[str, SubmissionResult]) -> None:
    want = EXPECTED[name]
    got = graded[name]
    assert got.valid is want["valid"], got.error
    if not want["valid"]:
        assert want["error"] in (got.error or "")
        assert all(i.status == "invalid" and i.points == 0 for i in got.items)
        return
    assert got.submission_id == want["submission_id"]
    for item in got.items:
        assert item.status in STATUSES
        if item.item in want["items"]:
            assert {"status": item.status, "mistake": item.mistake, "points": item.points} == want["items"][item.item], item.feedback
        else:
            assert item.status == want["others"], f"{item.item}: {item.feedback}"


def test_every_status_and_catalog_mistake_is_exercised(graded: dict[str, SubmissionResult], rubric) -> None:
    seen_status = {i.status for r in graded.values() for i in r.items}
    assert seen_status == set(STATUSES)
    seen = {(i.item, i.mistake) for r in graded.values() for i in r.items if i.status == "known_mistake"}
    listed = {(name, m.code) for name, item in rubric.items.items() for m in item.mistakes}
    assert listed <= seen, sorted(listed - seen)


def test_unit_mismatch_detail_names_units_and_factor(graded: dict[str, SubmissionResult]) -> None:
    item = next(i for i in graded["unit_kq_ft3.json"].items if i.item == "Kq")
    assert item.detail["unit_used"] == "ft³" and item.detail["unit_expected"] == "in³"
    assert item.detail["factor"] == pytest.approx(1 / 1728)
    assert "ft³ were used where in³ were needed" in item.feedback


def test_ecf_feedback_names_the_upstream_item(graded: dict[str, SubmissionResult]) -> None:
    kce = next(i for i in graded["ecf_kq.json"].items if i.item == "Kce")
    assert "your own Kq" in kce.feedback and kce.detail["from"] == ["Kq"]


def test_design_on_rig_limit_cycle_is_reported(graded: dict[str, SubmissionResult]) -> None:
    pi = next(i for i in graded["design_rig_limit_cycle.json"].items if i.item == "pi_design")
    assert pi.detail["stable"] and pi.detail["rig"] == "limit_cycle"
    assert "limit-cycle" in pi.feedback
