"""``grader demo``: the main job end to end on the embedded default station.

It is a scripted tour of the CLI, so every step is exactly what an instructor would run:
``key`` on the default dataset, ``grade`` on example submissions, ``check`` as a student,
``diagnose`` on the default dataset, and the ``survey`` and ``exam`` reports.
"""

from __future__ import annotations

from pathlib import Path

from rich.console import Console
from rich.rule import Rule

from grader.stations import reference_dir, repo_root

#: Example submissions graded by the demo (a correct one, unit slips, known mistakes, ECF, designs, a hostile one).
DEMO_SUBMISSIONS = (
    "correct.json", "unit_kq_ft3.json", "unit_beta_pa.json", "mistake_weight_as_mass.json", "mistake_hz.json",
    "ecf_kq.json", "bad_design_goal.json", "design_rig_limit_cycle.json", "tf_wrong.json", "hostile_import.json",
    "correct.xlsx",
)


def _steps(out: Path) -> list[tuple[str, list[str]]]:
    ref, root = reference_dir(), repo_root()
    fixtures = root / "submissions_fixtures"
    dataset = ref / "datasets" / "default"
    return [
        ("Answer key from the default station's lab dataset", ["key", str(dataset), "-o", str(out / "key.json")]),
        ("Grading example submissions (Canvas CSV, Gradescope JSON, feedback, gradebook)",
         ["grade", *[str(fixtures / "grading" / n) for n in DEMO_SUBMISSIONS], "--out", str(out / "grading"),
          "--no-progress"]),
        ("A student's self-check (never reveals the key)", ["check", str(fixtures / "grading" / "unit_kq_ft3.json")]),
        ("Sim-to-real gap diagnosis of the default dataset",
         ["diagnose", str(dataset), "--key", str(out / "key.json"), "--out", str(out / "diagnosis")]),
        ("Survey report (65 respondents, Qualtrics export)",
         ["survey", str(fixtures / "assessment" / "survey_qualtrics.csv"), "--out", str(out / "survey")]),
        ("Embedded exam-question report", ["exam", str(fixtures / "assessment" / "exam_scores.csv"), "--out", str(out / "exam")]),
    ]


def run_demo(out: Path) -> int:
    """Run every step into ``out``; returns 0 when each step ran (a step's failure is reported, not hidden)."""
    from grader.cli import main

    console = Console()
    out.mkdir(parents=True, exist_ok=True)
    failed = []
    for title, argv in _steps(out):
        console.print(Rule(f"[bold]{title}[/bold]"))
        shown = [_short(a) for a in argv]
        if argv[0] == "grade":
            shown[1:-3] = [shown[1], f"… ({len(argv) - 4} example submissions)"]
        console.print(f"$ grader {' '.join(shown)}", style="dim")
        if main(argv) != 0:
            failed.append(argv[0])
    console.print(Rule("[bold]Done[/bold]"))
    for name, what in (("key.json", "answer key"), ("grading/", "grades.csv, report.json, gradebook.xlsx, results/, feedback/"),
                       ("diagnosis/", "diagnosis.json, report.html, plots"), ("survey/", "report.xlsx, report.html, report.json, charts"),
                       ("exam/", "report.xlsx, report.html, report.json, chart")):
        console.print(f"  {out / name}: {what}")
    if failed:
        console.print(f"[red]steps that reported problems: {', '.join(failed)}[/red]")
        return 1
    return 0


def _short(arg: str) -> str:
    """Show paths relative to the checkout or the output folder."""
    for base in (repo_root(), Path.cwd()):
        try:
            return str(Path(arg).relative_to(base))
        except ValueError:
            continue
    return arg
