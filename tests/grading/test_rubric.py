"""The rubric schema: the shipped rubric loads; instructor mistakes are clear RubricErrors."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from grader.errors import RubricError
from grader.grading.items import ITEMS
from grader.grading.rubric import Tolerance, load_rubric

from .conftest import ROOT

SHIPPED = ROOT / "rubrics" / "hydraulic_positioner.yaml"


def test_shipped_rubric_covers_every_canonical_item() -> None:
    r = load_rubric(SHIPPED)
    assert list(r.items) == list(ITEMS) and r.max_score == 100
    order = r.order()
    for name, item in r.items.items():
        assert all(order.index(d) < order.index(name) for d in item.depends_on)


def _broken(tmp_path: Path, change) -> Path:
    raw = yaml.safe_load(SHIPPED.read_text())
    change(raw)
    path = tmp_path / "r.yaml"
    path.write_text(yaml.safe_dump(raw))
    return path


@pytest.mark.parametrize(("change", "message"), [
    (lambda r: r["items"].update(Kqq={"points": 1}), "unknown item 'Kqq'"),
    (lambda r: r["items"]["Kq"]["mistakes"].append({"code": "weight_as_mass"}), "not in the catalog for Kq"),
    (lambda r: r["items"]["Kce"].update(depends_on=["Kq", "nope"]), "'nope' is not an item"),
    (lambda r: r["items"]["Kq"].update(depends_on=["Kpot"]), "error carried forward for Kq can use none"),
    (lambda r: r["items"]["Kq"].update(unit="in^3/sx"), "unknown unit"),
    (lambda r: r["items"]["Kq"].update(points=-1), "greater than 0"),
    (lambda r: r["items"]["Kq"].update(tolerance={}), "at least one of"),
    (lambda r: r["items"]["pd_design"]["design"].update(goal_credit=0.9), "add up to 1"),
    (lambda r: r["items"]["Kq"].update(design={}), "'design' settings"),
    (lambda r: r.update(feedback_convention="amps"), "feedback_convention"),
    (lambda r: r.pop("items"), "items"),
])
def test_broken_rubrics(tmp_path: Path, change, message: str) -> None:
    with pytest.raises(RubricError, match=message):
        load_rubric(_broken(tmp_path, change))


def test_dependencies_must_be_inputs_of_the_recomputation(tmp_path: Path) -> None:
    with pytest.raises(RubricError, match="error carried forward for Kce can use omega_crit, Kp_crit, Kq, Kpot"):
        load_rubric(_broken(tmp_path, lambda r: r["items"]["Kce"].update(depends_on=["Kce"])))


def test_not_a_rubric(tmp_path: Path) -> None:
    (tmp_path / "x.yaml").write_text("- a\n- b\n")
    with pytest.raises(RubricError, match="mapping"):
        load_rubric(tmp_path / "x.yaml")
    with pytest.raises(RubricError, match="not found"):
        load_rubric(tmp_path / "missing.yaml")


@pytest.mark.parametrize(("tol", "value", "expected", "ok"), [
    (Tolerance(relative=0.05), 1.049, 1.0, True),
    (Tolerance(relative=0.05), 1.051, 1.0, False),
    (Tolerance(absolute=0.05), 0.04, 0.0, True),
    (Tolerance(sig_figs=3), 0.03855, 0.0385, True),
    (Tolerance(sig_figs=3), 0.0386, 0.0385, False),
    (Tolerance(interval=True), 1.2, 1.0, True),
])
def test_tolerance(tol: Tolerance, value: float, expected: float, ok: bool) -> None:
    assert tol.accepts(value, expected, absolute=0.05 if tol.absolute else 0.0, interval=(0.9, 1.3)) is ok
