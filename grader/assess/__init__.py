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

from grader.assess.exam_io import ExamData, read_exam_scores
from grader.assess.exam_report import build_exam_report
from grader.assess.mapping import SurveyMapping, load_mapping
from grader.assess.runner import run_exam, run_survey
from grader.assess.schemas import ExamReport, SurveyReport
from grader.assess.survey_io import SurveyData, read_survey
from grader.assess.survey_report import build_survey_report
from grader.assess.templates import write_exam_template, write_survey_template

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
