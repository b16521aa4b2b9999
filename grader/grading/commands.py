"""CLI verbs of the grading area: ``grade``, ``check``, ``template``, ``gradescope``, ``gradescope-package``."""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path
from typing import TYPE_CHECKING

from grader.errors import GraderError, SubmissionError
from grader.outpaths import output_file, output_folder

if TYPE_CHECKING:  # heavy modules are imported inside the handlers (fast start-up)
    from rich.table import Table

    from grader.grading.context import KeyStore
    from grader.grading.grade import GradeOptions
    from grader.grading.results import SubmissionResult
    from grader.grading.rubric import Rubric

DEFAULT_RUBRIC = "rubrics/hydraulic_positioner.yaml"


def _rubric_path(args: argparse.Namespace) -> Path:
    from grader.stations import repo_root

    return Path(args.rubric) if args.rubric else repo_root() / DEFAULT_RUBRIC


def _rubric(args: argparse.Namespace) -> Rubric:
    from grader.grading.rubric import load_rubric

    return load_rubric(_rubric_path(args))


def _options(args: argparse.Namespace, rubric: Rubric, *, reveal: bool) -> GradeOptions:
    from grader.grading.grade import GradeOptions

    return GradeOptions(rubric=rubric, convention=args.feedback_convention or rubric.feedback_convention, reveal=reveal)


def _store(args: argparse.Namespace) -> KeyStore:
    from grader.grading.context import KeyStore

    return KeyStore(datasets_dir=Path(args.datasets) if args.datasets else None,
                    keys_dir=Path(args.keys) if args.keys else None,
                    cache_dir=Path(args.key_cache) if args.key_cache else None)


def summary_table(results: list[SubmissionResult], rubric: Rubric) -> Table:
    """Per item: mean points, how many were correct, and the most common mistake."""
    from rich.table import Table

    table = Table(title=f"{len(results)} submissions, mean score "
                        f"{sum(r.score for r in results) / max(len(results), 1):.1f} / {rubric.max_score:g}")
    for col in ("item", "mean", "max", "correct", "most common mistake"):
        table.add_column(col, justify="right" if col in ("mean", "max", "correct") else "left")
    for name, item in rubric.items.items():
        got = [i for r in results for i in r.items if i.item == name]
        mistakes = Counter(i.mistake for i in got if i.mistake)
        top = min(mistakes.items(), key=lambda kv: (-kv[1], kv[0]), default=None)
        ok = sum(i.status in ("correct", "correct_ecf") for i in got)
        table.add_row(name, f"{sum(i.points for i in got) / max(len(got), 1):.2f}", f"{item.points:g}",
                      f"{ok}/{len(got)}", f"{top[0]} ({top[1]})" if top else "")
    return table


def _grade(args: argparse.Namespace) -> int:
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from grader.exports.bundle import write_outputs
    from grader.grading.pipeline import expand_inputs, grade_batch, passed_over, read_all
    from grader.grading.submissions import SUFFIXES

    for flag, given in (("--assignment", args.assignment), ("--assignment-id", args.assignment_id)):
        if given is not None and (not given.strip() or not given.isprintable()):  # it heads a grades.csv column
            raise GraderError(f"{flag}: {given[:60]!r} must be one line of text, not blank")
    out = output_folder(args.out)
    rubric = _rubric(args)
    opts = _options(args, rubric, reveal=True)
    paths = expand_inputs(args.submissions)
    skipped = passed_over(args.submissions)
    if not paths:
        raise SubmissionError("no submission files found (" + ", ".join(SUFFIXES) + ")" +
                              (f"; not submissions: {', '.join(f.name for f in skipped[:5])}" if skipped else ""))
    console = Console(stderr=True)
    subs = read_all(paths, opts)
    results: list[SubmissionResult] = []
    with Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                  console=console, disable=args.no_progress or not console.is_terminal) as progress:
        task = progress.add_task("grading", total=len(subs))
        stage = lambda s: progress.update(task, description=s)  # noqa: E731
        for r in grade_batch(subs, opts, _store(args), workers=args.workers, on_stage=stage):
            results.append(r)
            progress.advance(task)
    write_outputs(results, out, rubric, assignment=args.assignment or rubric.assignment.name,
                  assignment_id=args.assignment_id or rubric.assignment.id)
    Console().print(summary_table(results, rubric))
    print(f"wrote {len(results)} results to {args.out}/ (grades.csv, report.json, gradebook.xlsx, results/, feedback/)")
    if skipped:
        names = ", ".join(f.name for f in skipped[:10]) + (f" and {len(skipped) - 10} more" if len(skipped) > 10 else "")
        print(f"note: {len(skipped)} file(s) in the folders given are not submissions ({', '.join(SUFFIXES)}) and were "
              f"not graded: {names}", file=sys.stderr)
    _warn_duplicates(results)
    invalid = [r for r in results if not r.valid]
    if invalid:
        print(f"{len(invalid)} submission(s) could not be graded:", file=sys.stderr)
        for r in invalid:
            name, error = Path(r.source).name, r.error or "unknown error"
            print(f"  {error if error.startswith(name + ':') else f'{name}: {error}'}", file=sys.stderr)
        print("  (score 0; without readable students their grades.csv rows read '(unreadable submission ID: "
              "no student listed)')", file=sys.stderr)
        return 1
    return 0


def _warn_duplicates(results: list[SubmissionResult]) -> None:
    """Say which submissions grades.csv does not use because their students handed in later ones."""
    from grader.exports.bundle import source_times
    from grader.exports.canvas import latest, superseded

    times = source_times(results)
    gone = superseded(results, times)
    if gone:
        print(f"warning: {len(gone)} submission(s) share students with a later one; grades.csv grades each "
              "student's latest submission (by file time), report.json names it in 'superseded_by':", file=sys.stderr)
        chosen, key = latest(results, times)
        by_id = {r.submission_id: r for r in results}
        for sid, newer in sorted(gone.items()):
            to: dict[str, list[str]] = {}
            for s in by_id[sid].students:
                to.setdefault(chosen[key(s)].submission_id, []).append(s.name)
            kept = to.pop(sid, [])
            if kept or len(to) > 1:  # only some of its students moved, or they moved to different submissions
                moves = "; ".join(f"{', '.join(names)} -> {other}" for other, names in sorted(to.items()))
                still = f"; {', '.join(kept)} still graded on it" if kept else ""
                print(f"  {sid}: {moves}{still}", file=sys.stderr)
            else:
                print(f"  {sid} -> {newer}", file=sys.stderr)


def _check(args: argparse.Namespace) -> int:
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    from grader.grading.pipeline import resolve_key
    from grader.grading.selfcheck import self_check
    from grader.grading.submissions import read_submission

    rubric = _rubric(args)
    opts = _options(args, rubric, reveal=False)
    sub = read_submission(Path(args.submission), limits=opts.limits)  # an unreadable file: one line, exit 2
    store = _store(args)
    result = self_check(sub, lambda s: resolve_key(s, store), opts)
    console = Console(highlight=False)
    table = Table(title=escape(f"grader check: {sub.submission_id}"), show_lines=True)
    for col in ("item", "status", "feedback"):
        table.add_column(col, overflow="fold")
    for i in result.items:
        table.add_row(escape(i.item), i.status, escape(i.feedback))
    console.print(table)
    for note in result.notes:
        console.print(escape(f"note: {note}"))
    return 0


def _template(args: argparse.Namespace) -> int:
    from grader.exports.atomic import workbook_bytes
    from grader.grading.xlsx_io import build_template
    from grader.outpaths import write_bytes
    from grader.stations import load_station

    output_file(args.output, example="lab4.xlsx")
    rubric = _rubric(args)
    station = load_station(args.station)
    gain_unit = "dimensionless" if station.feedback == "volts" else "V/in"
    wb = build_template(list(rubric.items), station=station.station, gain_unit=gain_unit)
    out = write_bytes(args.output, workbook_bytes(wb))
    print(f"wrote {out} ({len(rubric.items)} items; fill the 'info', 'students' and 'answers' sheets)")
    return 0


def _gradescope(args: argparse.Namespace) -> int:
    from grader.exports.gradescope import results_json
    from grader.grading.grade import invalid_submission
    from grader.grading.submissions import SUFFIXES
    from grader.outpaths import write_text

    output_file(args.results, example="results.json")
    rubric = _rubric(args)
    opts = _options(args, rubric, reveal=args.reveal)
    folder = Path(args.submission_dir)
    found = _uploaded(folder)
    files = [f for f in found if f.suffix.lower() in SUFFIXES]
    if len(files) != 1:
        others = [f.relative_to(folder).as_posix() for f in found if f not in files][:5]
        what = (f"{len(files)} submission files ({', '.join(f.relative_to(folder).as_posix() for f in files)})" if files
                else "no submission file" + (f" (only {', '.join(others)})" if others else ""))
        result = invalid_submission("submission", str(folder), f"found {what}; upload exactly one "
                                    f"{'/'.join(SUFFIXES)} file", rubric)
    else:
        result = _grade_single(files[0], opts, _store(args), rubric)
    write_text(args.results, results_json(result))
    print(f"score {result.score:g} / {result.max_score:g}; wrote {args.results}")
    return 0


def _uploaded(folder: Path) -> list[Path]:
    """The files a student uploaded: those at the top of ``folder``, or, where none is a submission, those in its
    subfolders (a zip upload unpacks into one), without hidden files and macOS's ``__MACOSX`` copies."""
    from grader.grading.submissions import SUFFIXES

    if not folder.is_dir():
        return []
    shown = [f for f in sorted(folder.rglob("*")) if f.is_file()
             and not any(p.startswith(".") or p == "__MACOSX" for p in f.relative_to(folder).parts)]
    top = [f for f in shown if f.parent == folder]
    return top if any(f.suffix.lower() in SUFFIXES for f in top) else shown


def _grade_single(path: Path, opts: GradeOptions, store: KeyStore, rubric: Rubric) -> SubmissionResult:
    from grader.grading.grade import grade_submission, invalid_submission
    from grader.grading.pipeline import resolve_key
    from grader.grading.submissions import fallback_id, read_submission

    try:
        sub = read_submission(path, limits=opts.limits)
        return grade_submission(sub, resolve_key(sub, store), opts)
    except GraderError as exc:
        return invalid_submission(fallback_id(path), str(path), str(exc), rubric)


def _package(args: argparse.Namespace) -> int:
    from grader.exports.gradescope import package_zip
    from grader.outpaths import write_bytes
    from grader.stations import repo_root

    output_file(args.output, example="autograder.zip")
    rubric_path = _rubric_path(args)
    rubric = _rubric(args)
    data = package_zip(repo_root(), rubric_path, convention=args.feedback_convention or rubric.feedback_convention)
    out = write_bytes(args.output, data)
    print(f"wrote {out} ({len(data) / 1e6:.1f} MB): upload it as the Gradescope autograder (Ubuntu image)")
    return 0


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--rubric", help=f"rubric YAML (default: {DEFAULT_RUBRIC})")
    p.add_argument("--feedback-convention", choices=("volts", "inches"),
                   help="where Kpot sits in the loop for the transfer-function items (default: the rubric's)")
    p.add_argument("--datasets", help="folder of station datasets (default: reference_solutions/datasets)")
    p.add_argument("--keys", help="folder of checked-in keys (default: reference_solutions/keys)")
    p.add_argument("--key-cache", help="folder to keep keys built from datasets in (reused while the data are unchanged)")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("grade", help="grade submissions; write Canvas, Gradescope, feedback and gradebook outputs")
    p.add_argument("submissions", nargs="+", help="submission files (.json, .yaml, .xlsx), folders or globs")
    p.add_argument("-o", "--out", required=True, help="output folder")
    p.add_argument("--assignment", help="Canvas assignment name (default: the rubric's)")
    p.add_argument("--assignment-id", help="Canvas assignment id (default: the rubric's)")
    p.add_argument("--workers", type=int, default=2, help="worker processes (default: 2)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    _common(p)
    p.set_defaults(handler=_grade)
    p = sub.add_parser("check", help="check your submission before handing it in (never shows the key)")
    p.add_argument("submission", help="your submission file (.json, .yaml or .xlsx)")
    _common(p)
    p.set_defaults(handler=_check)
    p = sub.add_parser("template", help="write the XLSX submission template")
    p.add_argument("-o", "--out", "--output", dest="output", default="lab4.xlsx", help="workbook to write (default: lab4.xlsx)")
    p.add_argument("--rubric", help=f"rubric whose items the template lists (default: {DEFAULT_RUBRIC})")
    p.add_argument("--station", default="default", help="station (sets the gain units; default: default)")
    p.set_defaults(handler=_template)
    p = sub.add_parser("gradescope", help="grade inside Gradescope's autograder container")
    p.add_argument("--submission-dir", default="/autograder/submission", help="(default: /autograder/submission)")
    p.add_argument("--results", default="/autograder/results/results.json", help="(default: /autograder/results/results.json)")
    p.add_argument("--reveal", action="store_true", help="let feedback show key values (after the deadline)")
    _common(p)
    p.set_defaults(handler=_gradescope)
    p = sub.add_parser("gradescope-package", help="build the Gradescope autograder zip")
    p.add_argument("-o", "--out", "--output", dest="output", default="autograder.zip", help="zip to write (default: autograder.zip)")
    p.add_argument("--rubric", help=f"rubric to grade with (default: {DEFAULT_RUBRIC})")
    p.add_argument("--feedback-convention", choices=("volts", "inches"), help="(default: the rubric's)")
    p.set_defaults(handler=_package)
