"""Generate the assessment fixtures: one synthetic class, written in every supported form.

Run from anywhere: ``python submissions_fixtures/assessment/make_fixtures.py``.
Seeded, so re-running rewrites byte-identical files (XLSX timestamps are pinned).

The survey class is shaped like the paper's (Fall 2007, 65 students): the two
hydraulic labs rated highest (means around 4 and above), a few students who did
not do a lab, some blanks, and free-text answers naming labs. The exam class is
the paper's embedded question: students randomly split between the two
problems and between with/without a reference to the lab; the lab-reference
group does slightly worse and the groups are alike on the rest of the test.
"""

from __future__ import annotations

import csv
import io
import json
import random
import re
import sys
import zipfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1]))

from grader.assess.mapping import load_mapping  # noqa: E402  (needs the sys.path line above)

SEED = 2007
#: The exam class has its own seed, picked so that (as in the paper) the groups come out
#: alike on the rest of the test and the lab-reference group slightly worse on the item.
EXAM_SEED = 40
N_STUDENTS = 65
LABELS = ["Strongly Disagree", "Disagree", "Neutral", "Mostly Agree", "Completely Agree"]
#: Mean rating per lab and statement (simulink, models, controllers, intuition, time).
MEANS = {
    "motomatic": [3.4, 3.0, 3.0, 3.4, 3.3],
    "two_tank": [3.0, 3.2, 3.3, 3.1, 3.0],
    "hydraulic_positioner": [4.5, 4.4, 4.1, 4.4, 4.2],
    "hydraulic_pid": [3.9, 3.8, 4.1, 4.0, 4.1],
}
OVERALL_MEANS = {"learned_modeling": 4.3, "above_average": 3.9}
NOT_DONE = {"motomatic": 2, "two_tank": 4, "hydraulic_positioner": 1, "hydraulic_pid": 3}
OPENERS = {
    "hydraulic_positioner": ["The hydraulic positioner lab", "Hydraulic positioner", "The positioner lab",
                             "hydraulic positioner", "Hydraulic Positioner lab"],
    "hydraulic_pid": ["Hydraulic PID", "The PID lab", "Hydraulic PID controller lab"],
    "motomatic": ["Motomatic", "The Motomatic lab"],
    "two_tank": ["Two-tank lab", "The two tank lab"],
}
REASONS = {
    "hydraulic_positioner": [
        "the Simulink model actually matched the real system",
        "driving it unstable on purpose made root locus click for me",
        "it was the first time a linear model predicted what the hardware did",
        "I finally trusted block diagram reduction",
        "we characterized every parameter ourselves",
        "the step responses matched the simulation at three different gains",
        "the ramp response showed steady-state error exactly like in lecture",
    ],
    "hydraulic_pid": [
        "seeing the PI controller remove the ramp error was great",
        "we designed a controller and it worked on the real rig",
        "tuning gains on real hardware",
        "adding derivative gain cut the overshoot just as predicted",
    ],
    "motomatic": [
        "it was the first time I used Simulink for a real system",
        "friction showed me the limits of linear models",
        "it was easy to see what the gain does",
    ],
    "two_tank": ["the level control was intuitive", "the nonlinear tanks made me think about linearization"],
}
NO_LAB = ["The hydraulic one.", "All of them were useful in different ways.", "Not sure.",
          "The one with the big cylinder, it felt like real engineering."]
EMAIL_ANSWER = "Hydraulic positioner - happy to explain, email me at student107@example.edu"
MENTION_WEIGHTS = [("hydraulic_positioner", 26), ("hydraulic_pid", 10), ("motomatic", 6), ("two_tank", 3), (None, 5)]


def _rating(rng: random.Random, mean: float, lenience: float) -> int:
    return max(1, min(5, round(mean + lenience + rng.gauss(0, 0.75))))


def _answer(rng: random.Random) -> str:
    lab = rng.choices([m for m, _ in MENTION_WEIGHTS], [w for _, w in MENTION_WEIGHTS])[0]
    if lab is None:
        return rng.choice(NO_LAB)
    return f"{rng.choice(OPENERS[lab])}{rng.choice([', because ', ' - ', ': ', '; '])}{rng.choice(REASONS[lab])}."


def make_class(rng: random.Random) -> list[dict]:
    """One record per student: ratings (None = blank), did-lab flags, hours, answer."""
    not_done = {lab: set(rng.sample(range(N_STUDENTS), k)) for lab, k in NOT_DONE.items()}
    students = []
    for i in range(N_STUDENTS):
        lenience = rng.gauss(0, 0.55)
        did = {lab: i not in not_done[lab] for lab in MEANS}
        ratings = {
            (lab, j): (_rating(rng, mean, lenience) if did[lab] and rng.random() > 0.02 else None)
            for lab, means in MEANS.items()
            for j, mean in enumerate(means)
        }
        overall = {key: _rating(rng, mean, lenience) for key, mean in OVERALL_MEANS.items()}
        hours = None if rng.random() < 0.05 else rng.choice([1, 2, 2.5, 3, 3, 3.5, 4, 4, 4, 5, 5, 6, 8, 10])
        answer = _answer(rng) if rng.random() < 0.82 else ""
        students.append({"did": did, "ratings": ratings, "overall": overall, "hours": hours, "answer": answer})
    students[7]["answer"] = EMAIL_ANSWER  # a student who wrote their e-mail address: it must not be quoted
    # One student said "No" to the Two-Tank lab yet rated it: those ratings must be discarded.
    victim = sorted(not_done["two_tank"])[0]
    for j in range(5):
        students[victim]["ratings"][("two_tank", j)] = 3
    return students


def _hours_text(hours: float | None, google: bool, i: int) -> str:
    if hours is None:
        return ""
    if google and hours == 3.5:
        return "3-4"
    if google and i % 7 == 0:
        return f"{hours:g} hours"
    return f"{hours:g}"


def _cells(student: dict, mapping, form: str, i: int) -> dict[str, str]:
    """The answer of one student to every mapped column, as that form writes it."""
    out: dict[str, str] = {}
    for field in mapping.fields(form):
        if field.kind == "did_lab":
            out[field.header] = "Yes" if student["did"][field.lab] else "No"
        elif field.kind == "rating":
            j = [s.id for s in mapping.statements].index(field.statement)
            out[field.header] = _rating_text(student, field.lab, j, form, i)
        elif field.kind == "overall":
            value = student["overall"][field.statement]
            out[field.header] = LABELS[value - 1] if form == "google" else str(value)
        elif field.kind == "hours":
            out[field.header] = _hours_text(student["hours"], form == "google", i)
        else:
            out[field.header] = student["answer"]
    return out


def _rating_text(student: dict, lab: str, j: int, form: str, i: int) -> str:
    value = student["ratings"][(lab, j)]
    if value is None:
        if form == "template" and not student["did"][lab] and i % 2 == 0:
            return "Did not do this lab"
        return "N/A" if form == "template" and i % 5 == 0 else ""
    return LABELS[value - 1] if form == "google" else str(value)


def write_csv(path: Path, rows: list[list[str]]) -> None:
    buffer = io.StringIO()
    csv.writer(buffer, lineterminator="\n").writerows(rows)
    path.write_text(buffer.getvalue(), encoding="utf-8")


def template_rows(students: list[dict], mapping) -> list[list[str]]:
    fields = mapping.fields("template")
    header = ["respondent"] + [f.header for f in fields]
    rows = [header]
    for i, student in enumerate(students):
        cells = _cells(student, mapping, "template", i)
        rows.append([f"anon-{0x5A00 + 37 * i:04x}"] + [cells[f.header] for f in fields])
    return rows


QUALTRICS_META = [
    ("StartDate", "Start Date", '{"ImportId":"startDate","timeZone":"America/Los_Angeles"}'),
    ("EndDate", "End Date", '{"ImportId":"endDate","timeZone":"America/Los_Angeles"}'),
    ("Status", "Response Type", '{"ImportId":"status"}'),
    ("IPAddress", "IP Address", '{"ImportId":"ipAddress"}'),
    ("Progress", "Progress", '{"ImportId":"progress"}'),
    ("Duration (in seconds)", "Duration (in seconds)", '{"ImportId":"duration"}'),
    ("Finished", "Finished", '{"ImportId":"finished"}'),
    ("RecordedDate", "Recorded Date", '{"ImportId":"recordedDate","timeZone":"America/Los_Angeles"}'),
    ("ResponseId", "Response ID", '{"ImportId":"_recordId"}'),
    ("DistributionChannel", "Distribution Channel", '{"ImportId":"distributionChannel"}'),
    ("UserLanguage", "User Language", '{"ImportId":"userLanguage"}'),
]


def _qualtrics_text(field, mapping) -> str:
    if field.kind == "rating":
        lab = mapping.lab(field.lab)
        return f"The {lab.name} Laboratory: - {mapping.statement(field.statement).text}"
    if field.kind == "did_lab":
        return f"Did you do the {mapping.lab(field.lab).name} Laboratory?"
    if field.kind == "overall":
        return f"Overall the ME 422 Laboratory: - {next(o.text for o in mapping.overall if o.id == field.statement)}"
    return {"hours": "Hours per week outside lab", "most_useful": "Most useful lab, and why?"}[field.kind]


def qualtrics_rows(students: list[dict], mapping, rng: random.Random) -> list[list[str]]:
    fields = mapping.fields("qualtrics")
    rows = [
        [m[0] for m in QUALTRICS_META] + [f.header for f in fields],
        [m[1] for m in QUALTRICS_META] + [_qualtrics_text(f, mapping) for f in fields],
        [m[2] for m in QUALTRICS_META] + [json.dumps({"ImportId": "QID" + f.header[1:]}) for f in fields],
    ]
    preview = dict(students[0], answer="testing the survey")
    for i, student in enumerate([preview, *students]):
        cells = _cells(student, mapping, "qualtrics", i)
        status = "Survey Preview" if i == 0 else "IP Address"
        start = f"2007-12-{3 + i // 30:02d} {9 + i % 8:02d}:{(7 * i) % 60:02d}:00"
        meta = [start, start, status, f"192.0.2.{10 + i}", "100", str(200 + rng.randrange(600)), "True",
                start, "R_" + "".join(rng.choices("ABCDEFGHJKLMNPQRSTUVWXYZabcdefghijkmnopqrstuvwxyz0123456789", k=15)),
                "anonymous", "EN"]
        rows.append(meta + [cells[f.header] for f in fields])
    return rows


def google_rows(students: list[dict], mapping) -> list[list[str]]:
    fields = mapping.fields("google")
    rows = [["Timestamp", "Email Address"] + [f.header for f in fields]]
    for i, student in enumerate(students):
        cells = _cells(student, mapping, "google", i)
        stamp = f"12/{3 + i // 30}/2007 {9 + i % 8}:{(7 * i) % 60:02d}:{(13 * i) % 60:02d}"
        rows.append([stamp, f"student{100 + i}@example.edu"] + [cells[f.header] for f in fields])
    return rows


def write_xlsx(path: Path, rows: list[list[str]]) -> None:
    """Write rows (numbers as numbers) to XLSX, then pin every timestamp in the zip."""
    from openpyxl import Workbook

    workbook = Workbook()
    sheet = workbook.active
    sheet.title = "Responses"
    for row in rows:
        sheet.append([_xlsx_value(cell) for cell in row])
    buffer = io.BytesIO()
    workbook.save(buffer)
    pinned = io.BytesIO()
    with zipfile.ZipFile(buffer) as src, zipfile.ZipFile(pinned, "w", zipfile.ZIP_DEFLATED) as dst:
        for info in src.infolist():
            data = src.read(info.filename)
            if info.filename == "docProps/core.xml":
                data = re.sub(rb"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ", b"2007-12-10T00:00:00Z", data)
            dst.writestr(zipfile.ZipInfo(info.filename, date_time=(2007, 12, 10, 0, 0, 0)), data,
                         compress_type=zipfile.ZIP_DEFLATED)
    path.write_bytes(pinned.getvalue())


def _xlsx_value(cell: str) -> object:
    if cell == "":
        return None
    try:
        number = float(cell)
    except ValueError:
        return cell
    return int(number) if number.is_integer() else number


def exam_rows(rng: random.Random) -> list[list[str]]:
    """The embedded exam question: random problem × group, slight deficit with the lab reference."""
    groups = ("with_lab_reference", "without_lab_reference")
    cells = [(p, g) for p in ("bode_tf_id", "p_controller_design") for g in groups]
    assignment = [cells[i % 4] for i in range(N_STUDENTS)]
    rng.shuffle(assignment)
    item_max = {"bode_tf_id": 20, "p_controller_design": 15}
    rows = [["student", "group", "problem", "item_score", "item_max", "total_score", "total_max"]]
    for i, (problem, group) in enumerate(assignment):
        ability = rng.gauss(0, 1)
        rest_max = 100 - item_max[problem]
        rest = max(0, min(rest_max, round(rest_max * (0.72 + 0.11 * ability + rng.gauss(0, 0.06)))))
        shift = -0.05 if group == "with_lab_reference" else 0.0
        share = 0.66 + 0.14 * ability + shift + rng.gauss(0, 0.15)
        item = max(0, min(item_max[problem], round(2 * item_max[problem] * share) / 2))
        rows.append([f"s{7100231 + 97 * i}", group, problem, f"{item:g}", str(item_max[problem]),
                     f"{rest + item:g}", "100"])
    return rows


def bad_files(template: list[list[str]], exam: list[list[str]]) -> dict[str, list[list[str]]]:
    """Deliberately broken copies, one problem each."""
    header = template[0]
    misspelt = [[h.replace("hydraulic_positioner.simulink", "hydraulic_positoner.simulink") for h in header]]
    seven = [row[:] for row in template]
    seven[12][header.index("hydraulic_pid.models")] = "7"
    keep = [i for i, h in enumerate(header) if not h.startswith("two_tank.")]
    no_lab = [[row[i] for i in keep] for row in template]
    exam_header = [["student", "group", "problem", "score", "item_max", "total_score", "total_max"], *exam[1:]]
    exam_over = [row[:] for row in exam]
    exam_over[5][3] = str(int(exam_over[5][4]) + 5)
    return {
        "survey_bad_header.csv": misspelt + template[1:],
        "survey_bad_value_7.csv": seven,
        "survey_missing_lab.csv": no_lab,
        "exam_bad_header.csv": exam_header,
        "exam_bad_score.csv": exam_over,
    }


def main(out: Path = HERE) -> None:
    """Write every fixture into ``out`` (by default, next to this script)."""
    rng = random.Random(SEED)
    mapping = load_mapping()
    students = make_class(rng)
    template = template_rows(students, mapping)
    write_csv(out / "survey_template.csv", template)
    write_xlsx(out / "survey_template.xlsx", template)
    write_csv(out / "survey_qualtrics.csv", qualtrics_rows(students, mapping, rng))
    write_csv(out / "survey_google_forms.csv", google_rows(students, mapping))
    exam = exam_rows(random.Random(EXAM_SEED))
    write_csv(out / "exam_scores.csv", exam)
    for name, rows in bad_files(template, exam).items():
        write_csv(out / name, rows)
    (out / "survey_empty.csv").write_bytes(b"")


if __name__ == "__main__":
    main()
