"""Assessment reports: the Likert lab survey and the embedded exam question.

Public API::

    run_survey(responses, out_dir, mapping_path=None) -> SurveyReport   # read, analyse, write files
    run_exam(scores, out_dir) -> ExamReport
    load_mapping(path=None) -> SurveyMapping        # None: the paper's Figure 10 form
    read_survey(path, mapping) -> SurveyData        # template, Qualtrics or Google Forms
    build_survey_report(data, mapping) -> SurveyReport
    read_exam_scores(path) -> ExamData
    build_exam_report(data) -> ExamReport
    write_survey_template(path, mapping), write_exam_template(path)

Modules, bottom up: ``likert`` (cell parsing), ``tables`` (CSV/XLSX to text),
``mapping`` (the YAML mapping), ``survey_io`` / ``exam_io`` (readers),
``stats`` / ``exam_stats`` (statistics), ``claims`` and ``free_text``,
``schemas`` (report.json), ``survey_report`` / ``exam_report`` (builders),
``views``, ``plots``, ``render_html``, ``render_xlsx``, ``templates``, ``runner``
and ``commands`` (the CLI verbs).
"""

from importlib import import_module
from typing import Any

#: Public name -> defining module (imported on first use, so the CLI starts fast).
_EXPORTS = {
    "ExamData": "exam_io", "read_exam_scores": "exam_io", "build_exam_report": "exam_report",
    "SurveyMapping": "mapping", "load_mapping": "mapping", "run_exam": "runner", "run_survey": "runner",
    "ExamReport": "schemas", "SurveyReport": "schemas", "SurveyData": "survey_io", "read_survey": "survey_io",
    "build_survey_report": "survey_report", "write_exam_template": "templates",
    "write_survey_template": "templates",
}


def __getattr__(name: str) -> Any:
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(import_module(f"{__name__}.{_EXPORTS[name]}"), name)


__all__ = [
    "ExamData",
    "ExamReport",
    "SurveyData",
    "SurveyMapping",
    "SurveyReport",
    "build_exam_report",
    "build_survey_report",
    "load_mapping",
    "read_exam_scores",
    "read_survey",
    "run_exam",
    "run_survey",
    "write_exam_template",
    "write_survey_template",
]
