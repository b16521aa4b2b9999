"""The assessment verbs: ``survey``, ``survey-template``, ``exam`` and ``exam-template``."""

from __future__ import annotations

import argparse
from pathlib import Path

from grader.outpaths import output_file, output_folder

_MAPPING_HELP = "YAML mapping of columns to lab × statement (default: the paper's Figure 10 form)"


def _survey(args: argparse.Namespace) -> int:
    from grader.assess.runner import run_survey, survey_files

    report = run_survey(args.responses, output_folder(args.out), args.mapping)
    print(f"{report.respondents} respondents ({report.form} form); wrote {', '.join(survey_files(report))} "
          f"to {args.out}")
    for comparison in report.comparisons:
        print(f"- {comparison.conclusion}")
    return 0


def _survey_template(args: argparse.Namespace) -> int:
    from grader.assess.mapping import load_mapping
    from grader.assess.templates import write_survey_template

    write_survey_template(output_file(args.out, example="survey.xlsx"), load_mapping(args.mapping))
    print(f"wrote {args.out}")
    return 0


def _exam(args: argparse.Namespace) -> int:
    from grader.assess.runner import EXAM_CHARTS, run_exam

    report = run_exam(args.scores, output_folder(args.out))
    print(f"{report.students} students; wrote report.json, report.html, report.xlsx and "
          f"{', '.join(EXAM_CHARTS.values())} to {args.out}")
    for line in report.next_study[:1]:
        print(f"- {line}")
    return 0


def _exam_template(args: argparse.Namespace) -> int:
    from grader.assess.templates import write_exam_template

    write_exam_template(output_file(args.out, example="exam_scores.xlsx"))
    print(f"wrote {args.out}")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the assessment verbs to the ``grader`` command line."""
    survey = subparsers.add_parser(
        "survey", help="Likert survey report (template, Qualtrics or Google Forms export)",
        description="Summarise the student laboratory survey: per lab × statement figures, "
        "Cronbach's alpha, Friedman/Wilcoxon comparisons across labs, hours and free text.",
    )
    survey.add_argument("responses", type=Path, metavar="RESPONSES", help="CSV or XLSX file of responses")
    survey.add_argument("-o", "--out", type=Path, required=True, metavar="DIR", help="folder for the report files")
    survey.add_argument("--mapping", type=Path, metavar="YAML", help=_MAPPING_HELP)
    survey.set_defaults(handler=_survey)

    template = subparsers.add_parser("survey-template", help="write a blank survey template (.csv or .xlsx)")
    template.add_argument("-o", "--out", type=Path, required=True, metavar="FILE", help="template file to write")
    template.add_argument("--mapping", type=Path, metavar="YAML", help=_MAPPING_HELP)
    template.set_defaults(handler=_survey_template)

    exam = subparsers.add_parser(
        "exam", help="embedded exam-question report (with vs without lab reference)",
        description="Compare the groups given a problem with and without a reference to the lab, "
        "per problem and overall, with item analysis and a power analysis.",
    )
    exam.add_argument("scores", type=Path, metavar="SCORES", help="CSV or XLSX, one row per student")
    exam.add_argument("-o", "--out", type=Path, required=True, metavar="DIR", help="folder for the report files")
    exam.set_defaults(handler=_exam)

    exam_template = subparsers.add_parser("exam-template", help="write a blank exam-score template (.csv or .xlsx)")
    exam_template.add_argument("-o", "--out", type=Path, required=True, metavar="FILE", help="template file to write")
    exam_template.set_defaults(handler=_exam_template)
