"""Regenerate the docs' figures from real outputs: ``python docs/gen_figures.py``.

Each figure is a file that a page's own runnable commands write (see ``runnable.py``): the
page's commands are run on the embedded default data in a scratch folder and the file is
copied to ``docs/figures/``. ``tests/docs/test_docs_commands.py`` runs the same commands and
fails when a committed figure no longer matches what they produce.
"""

from __future__ import annotations

import shutil
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from runnable import DOCS, make_workspace, page_commands, problems, run  # noqa: E402

FIGURES_DIR = DOCS / "figures"

#: figure file in docs/figures → (page whose commands make it, path they write, relative to their folder)
FIGURES: dict[str, tuple[str, str]] = {
    "diagnosis-step-kp10.png": ("tutorials/lab-staff.md", "diagnosis/run_step_kp10.png"),
    "diagnosis-candidates.png": ("tutorials/lab-staff.md", "diagnosis/candidates.png"),
    "survey-ratings.png": ("how-to/import-a-survey.md", "survey-report/survey_ratings.png"),
}


def figures_of(page: str) -> dict[str, str]:
    return {fig: produced for fig, (src, produced) in FIGURES.items() if src == page}


def run_page(page: str, folder: Path) -> list[str]:
    """Run every command of ``page`` in ``folder`` (a fresh workspace); returns the problems found."""
    make_workspace(folder)
    found: list[str] = []
    for command in page_commands(DOCS / page):
        code, output = run(command, folder)
        found += problems(command, code, output)
    return found


def main() -> int:
    FIGURES_DIR.mkdir(exist_ok=True)
    for page in sorted({src for src, _ in FIGURES.values()}):
        with tempfile.TemporaryDirectory() as tmp:
            found = run_page(page, Path(tmp))
            if found:
                print("\n".join(found), file=sys.stderr)
                return 1
            for fig, produced in figures_of(page).items():
                shutil.copyfile(Path(tmp) / produced, FIGURES_DIR / fig)
                print(f"wrote docs/figures/{fig}  (from {page}: {produced})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
