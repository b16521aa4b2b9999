"""Every runnable command in the docs runs on the embedded default data and says what the page says.

A page's ```console blocks run in order in a fresh copy of the embedded data (docs/runnable.py);
the figures the pages show must be what those commands write (docs/gen_figures.py).
"""

from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path

import numpy as np
import pytest
from matplotlib.image import imread

DOCS = Path(__file__).resolve().parents[2] / "docs"
sys.path.insert(0, str(DOCS))
_spec = importlib.util.spec_from_file_location("gen_figures", DOCS / "gen_figures.py")
gen_figures = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(gen_figures)
runnable = sys.modules["runnable"]

PAGES = [p.relative_to(DOCS).as_posix() for p in runnable.pages_with_commands()]


def test_the_tutorials_have_runnable_commands() -> None:
    assert {"tutorials/instructor.md", "tutorials/student.md", "tutorials/lab-staff.md"} <= set(PAGES)


@pytest.mark.parametrize("page", PAGES)
def test_page_commands(page: str, tmp_path: Path) -> None:
    assert gen_figures.run_page(page, tmp_path) == []
    for fig, produced in gen_figures.figures_of(page).items():
        made, shown = imread(tmp_path / produced), imread(gen_figures.FIGURES_DIR / fig)
        assert made.shape == shown.shape, f"docs/figures/{fig} is stale: run python docs/gen_figures.py"
        assert np.abs(made - shown).mean() < 0.01, f"docs/figures/{fig} is stale: run python docs/gen_figures.py"


def test_every_figure_comes_from_the_script() -> None:
    shown = set()
    for page in DOCS.rglob("*.md"):
        shown |= set(re.findall(r"!\[[^\]]*\]\(([^)]+)\)", page.read_text(encoding="utf-8")))
    names = {Path(s).name for s in shown}
    assert all(Path(s).parent.name == "figures" for s in shown)
    assert names == set(gen_figures.FIGURES) == {p.name for p in gen_figures.FIGURES_DIR.glob("*.png")}


def test_output_check_can_fail() -> None:
    """The checker rejects a wrong exit code and output the command did not print."""
    cmd = runnable.Command("x.md", 1, "grader --version", 0, ["grader 0.1", "no such line"])
    assert len(runnable.problems(cmd, 0, "grader 0.1.0\n")) == 1
    assert len(runnable.problems(cmd, 2, "grader 0.1.0\n no such  line")) == 1
    assert runnable.problems(cmd, 0, "grader 0.1.0\nno such\nline") == []


def test_output_check_reads_wrapped_table_cells() -> None:
    cmd = runnable.Command("x.md", 1, "grader check f.json", 0, ["the loop's is of degree 3."])
    wrapped = "│ closed_loop_tf │ incorrect │ the loop's is of │\n│                │           │ degree 3.        │\n"
    assert runnable.problems(cmd, 0, wrapped) == []
    assert len(runnable.problems(cmd, 0, wrapped.replace("degree", "order"))) == 1
