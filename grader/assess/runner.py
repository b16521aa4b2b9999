"""Run an analysis end to end: read the input, build the report, write every output file.

Outputs in ``out_dir``: ``report.json`` (the pydantic report, byte-identical for
the same input), ``report.html`` (self-contained), ``report.xlsx`` and the PNG charts.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from grader.assess import plots
from grader.assess.exam_io import read_exam_scores
from grader.assess.exam_report import build_exam_report, exam_frame
from grader.assess.mapping import load_mapping
from grader.assess.render_html import exam_html, survey_html
from grader.assess.render_xlsx import write_exam_xlsx, write_survey_xlsx
from grader.assess.schemas import ExamReport, SurveyReport
from grader.assess.survey_io import read_survey
from grader.assess.survey_report import build_survey_report
from grader.errors import AssessmentError

SURVEY_CHARTS = {"likert": "survey_ratings.png", "hours": "survey_hours.png"}
EXAM_CHARTS = {"exam": "exam_scores.png"}


def _prepare(out_dir: Path) -> Path:
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise AssessmentError(f"{out}: cannot create the output folder ({exc.strerror})") from exc
    return out


def _write(out: Path, report: SurveyReport | ExamReport, html: str, images: Mapping[str, bytes],
           names: Mapping[str, str], xlsx_writer) -> None:
    try:
        (out / "report.json").write_text(report.model_dump_json(indent=2) + "\n", encoding="utf-8")
        (out / "report.html").write_text(html, encoding="utf-8")
        for key, png in images.items():
            (out / names[key]).write_bytes(png)
        xlsx_writer(report, images, out / "report.xlsx")
    except OSError as exc:
        raise AssessmentError(f"{out}: cannot write the report ({exc.strerror})") from exc


def survey_files(report: SurveyReport) -> list[str]:
    """Names of the files :func:`run_survey` writes for this report."""
    charts = [SURVEY_CHARTS["likert"]]
    if report.hours is not None and report.hours.n:
        charts.append(SURVEY_CHARTS["hours"])
    return ["report.json", "report.html", "report.xlsx", *charts]


def run_survey(responses: Path, out_dir: Path, mapping_path: Path | None = None) -> SurveyReport:
    """Analyse a survey file and write the survey report files."""
    mapping = load_mapping(mapping_path)
    report = build_survey_report(read_survey(responses, mapping), mapping)
    images = {"likert": plots.likert_chart(report)}
    if report.hours is not None and report.hours.n:
        images["hours"] = plots.hours_chart(report.hours)
    out = _prepare(out_dir)
    _write(out, report, survey_html(report, images), images, SURVEY_CHARTS, write_survey_xlsx)
    return report


def run_exam(scores: Path, out_dir: Path) -> ExamReport:
    """Analyse an exam-score file and write the exam report files."""
    data = read_exam_scores(scores)
    report = build_exam_report(data)
    images = {"exam": plots.exam_chart(exam_frame(data), report)}
    out = _prepare(out_dir)
    _write(out, report, exam_html(report, images), images, EXAM_CHARTS, write_exam_xlsx)
    return report
