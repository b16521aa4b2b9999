"""XLSX submissions: the reader (openpyxl, read-only, formulas detected not evaluated) and the template.

Sheets: ``info`` (field | value: submission_id, station), ``students`` (name | sis_user_id |
login_id | section), ``answers`` (item | value | unit | expected unit | description; design
parts as ``pd_design.Kp``), optional ``poles`` (Kp | Ki | Kd | real [1/s] | imag [1/s]) and the
optional data sheets ``calibration``, ``flow``, ``friction`` (headers ``name [unit]``), ``runs``
(name | kind | Kp | Ki | Kd) and one sheet per run (t [s] | r [in] | y [in]).
"""

from __future__ import annotations

import datetime as dt
import difflib
import xml.etree.ElementTree as ET
import zipfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from openpyxl import Workbook, load_workbook
from openpyxl.worksheet.datavalidation import DataValidation

from grader.errors import SubmissionError
from grader.grading.items import ITEMS, MAY_BE_NOT_IDENTIFIABLE, MAY_BE_NOT_REACHABLE
from grader.grading.limits import DEFAULT_LIMITS, Limits
from grader.grading.results import Student
from grader.grading.submissions import (
    InlineData,
    InvalidAnswer,
    Submission,
    canonical_answers,
    safe_id,
)

DATA_SHEETS = {"calibration": ("position [in]", "voltage [V]"), "flow": ("input [V]", "flow [in^3/s]"),
               "friction": ("speed [in/s]", "force [lbf]")}
RUN_HEADER = ("t [s]", "r [in]", "y [in]")
STUDENT_FIELDS = ("name", "sis_user_id", "login_id", "section")
DESIGN_PARTS = {"pd_design": ("Kp", "Kd", "overshoot"), "pi_design": ("Kp", "Ki", "ramp_error")}
MAX_ROWS = 200_000


def _check_zip(path: Path, limits: Limits) -> None:
    size = path.stat().st_size
    if size > limits.max_xlsx_bytes:
        raise SubmissionError(f"{path.name}: file is {size / 1e6:.1f} MB; the limit is {limits.max_xlsx_bytes / 1e6:g} MB")
    if not zipfile.is_zipfile(path):
        raise SubmissionError(f"{path.name}: not an XLSX workbook (not a zip archive)")
    with zipfile.ZipFile(path) as z:
        infos = z.infolist()
        if len(infos) > 10_000 or sum(i.file_size for i in infos) > limits.max_xlsx_unzipped:
            raise SubmissionError(f"{path.name}: workbook unpacks to more than {limits.max_xlsx_unzipped / 1e6:g} MB")


def _rows(ws: Any, sheet: str, limit: int = MAX_ROWS) -> Iterator[list[Any]]:
    """Cell values row by row; a formula cell in a data sheet is an error naming the cell."""
    for n, row in enumerate(ws.iter_rows()):
        if n >= limit:
            raise SubmissionError(f"sheet {sheet!r}: more than {limit} rows")
        yield [c for c in row]


def _cell_value(c: Any, where: str, limits: Limits) -> Any:
    if c is None or c.value is None:
        return None
    if c.data_type == "f":
        return InvalidAnswer(f"cell {c.coordinate} holds a formula ({str(c.value)[:40]}); type the value itself")
    v = c.value
    if isinstance(v, (dt.datetime, dt.date, dt.time)):
        return InvalidAnswer(f"cell {c.coordinate}: Excel turned the entry into a date; format the cell as text")
    if isinstance(v, bool):
        return InvalidAnswer(f"cell {c.coordinate}: TRUE/FALSE is not an answer")
    if isinstance(v, str) and len(v) > limits.max_string:
        return InvalidAnswer(f"cell {c.coordinate}: text longer than {limits.max_string} characters")
    return v


def _plain(v: Any, where: str) -> Any:
    """A value in a non-answer sheet: an unreadable cell is the submission's error."""
    if isinstance(v, InvalidAnswer):
        raise SubmissionError(f"{where}: {v.reason}")
    return v


#: The info sheet's fields (its header row says ``field``); the station's data come from the data sheets.
INFO_FIELDS = ("submission_id", "station")


def _info(wb: Any, name: str, limits: Limits) -> tuple[dict[str, Any], list[str]]:
    """The info sheet's fields (letter case aside), and notes on rows it does not read. A field close to a known
    one (a misspelt ``station`` would grade against the default station) or ``data`` (a workbook's data are its
    sheets) is refused."""
    out, notes = {}, []
    for r, row in enumerate(_rows(wb["info"], "info", 50), start=1):
        cells = [_plain(_cell_value(c, "info", limits), f"{name}: sheet 'info'") for c in row[:2]]
        if len(cells) == 2 and isinstance(cells[0], str) and cells[0].strip():
            key = cells[0].strip()
            if key.casefold() in INFO_FIELDS:
                out[key.casefold()] = cells[1]
            elif not (r == 1 and key.casefold() == "field"):
                near = difflib.get_close_matches(key.casefold(), INFO_FIELDS, n=1)
                if key.casefold() == "data" or near:
                    why = ("a workbook carries its group's data in the data sheets (calibration, flow, friction, runs)"
                           if not near else f"did you mean {near[0]!r}?")
                    raise SubmissionError(f"{name}: sheet 'info' row {r}: unknown field {key[:40]!r}; {why}")
                notes.append(f"sheet 'info' row {r}: field {key[:40]!r} is not read (the fields are "
                             f"{', '.join(INFO_FIELDS)})")
    return out, notes


def _students(wb: Any, name: str, limits: Limits) -> tuple[Student, ...]:
    rows = list(_rows(wb["students"], "students", 20))
    out = []
    for r, row in enumerate(rows[1:], start=2):
        vals = [_plain(_cell_value(c, "students", limits), f"{name}: sheet 'students' row {r}") for c in row[:4]]
        vals = ["" if v is None else str(v).strip() for v in vals] + [""] * (4 - len(vals))
        if vals[0]:
            out.append(Student(*(v[:200] for v in vals[:4])))
    if not out:
        raise SubmissionError(f"{name}: sheet 'students' lists no student (name in column A, from row 2)")
    return tuple(out)


def _answer(value: Any, unit: Any) -> Any:
    if isinstance(value, InvalidAnswer) or value is None:
        return value
    if isinstance(unit, InvalidAnswer):
        return unit
    unit = str(unit).strip() if unit is not None else ""
    text = repr(value) if isinstance(value, float) else str(value)
    if unit and isinstance(value, str) and any(c.isdigit() for c in text) and any(c.isalpha() for c in text) \
            and not _bare_number(text):  # a number with a unit of its own (letters: not 0,04 nor 7.5×10⁻⁴)
        if text.replace(" ", "").endswith(unit.replace(" ", "")):  # the same unit in both: given once
            return text
        return InvalidAnswer(f"the value {text[:40]!r} carries its own unit and the unit column says {unit[:40]!r}; "
                             "give the unit once")
    return f"{text} {unit}" if unit else (value if isinstance(value, (int, float)) else text)


def _bare_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _columns(header: list[Any]) -> tuple[int, int, int]:
    """Columns of item, value and unit, found by the header row's names (a column inserted before them moves
    them); the template's A, B, C where the header does not name them."""
    names = [str(c.value).strip().casefold() if c is not None and isinstance(c.value, str) else "" for c in header]
    if "item" not in names or "value" not in names:
        return 0, 1, 2
    return names.index("item"), names.index("value"), names.index("unit") if "unit" in names else -1


def _answers(wb: Any, name: str, limits: Limits) -> dict[str, Any]:
    out: dict[str, Any] = {}
    rows: dict[str, int] = {}  # item (or design part) -> the row that answers it
    table = list(_rows(wb["answers"], "answers", 300))
    cols = _columns(table[0] if table else [])
    for r, row in enumerate(table[1:], start=2):
        item, value, unit = (_cell_value(row[j], "answers", limits) if 0 <= j < len(row) else None for j in cols)
        if not isinstance(item, str) or not item.strip() or value is None:  # no item, or the template's blank row
            continue
        item = item.strip()
        if item in rows:
            raise SubmissionError(f"{name}: sheet 'answers' row {r}: {item[:40]!r} is also answered on row "
                                  f"{rows[item]}; give each answer once")
        rows[item] = r
        head, _, part = item.partition(".")
        if head in DESIGN_PARTS and part:
            out.setdefault(head, {})
            if isinstance(out[head], dict):
                out[head][part] = _answer(value, unit)
        else:
            out[item] = _answer(value, unit)
    for head in DESIGN_PARTS:
        parts = out.get(head)
        if isinstance(parts, dict):
            bad = next((v for v in parts.values() if isinstance(v, InvalidAnswer)), None)
            out[head] = bad or ({k: v for k, v in parts.items() if v is not None} or None)
    return out


def _poles(wb: Any, limits: Limits) -> Any:
    groups: dict[tuple[float, float, float], list[list[float]]] = {}
    for r, row in enumerate(list(_rows(wb["poles"], "poles", 500))[1:], start=2):
        vals = [_cell_value(c, "poles", limits) for c in row[:5]] + [None] * 5
        if all(v is None for v in vals[:5]):
            continue
        bad = next((v for v in vals[:5] if isinstance(v, InvalidAnswer)), None)
        if bad:
            return bad
        if not all(isinstance(v, (int, float)) or v is None for v in vals[:5]) or vals[0] is None or vals[3] is None:
            return InvalidAnswer(f"sheet 'poles' row {r}: Kp and the real part must be numbers")
        key = (float(vals[0]), float(vals[1] or 0.0), float(vals[2] or 0.0))
        groups.setdefault(key, []).append([float(vals[3]), float(vals[4] or 0.0)])
    return [{"Kp": k[0], "Ki": k[1], "Kd": k[2], "poles": p} for k, p in groups.items()] or None


def _csv(wb: Any, sheet: str, name: str, limits: Limits) -> str | None:
    lines = []
    for r, row in enumerate(_rows(wb[sheet], sheet), start=1):
        vals = [_plain(_cell_value(c, sheet, limits), f"{name}: sheet {sheet!r} row {r}") for c in row]
        if all(v is None for v in vals):
            continue
        lines.append(",".join("" if v is None else (repr(v) if isinstance(v, float) else str(v)) for v in vals))
    return "\n".join(lines) + "\n" if len(lines) > 1 else None


def _data(wb: Any, name: str, limits: Limits) -> InlineData | None:
    files = {f"{s}.csv": text for s in DATA_SHEETS if s in wb.sheetnames and (text := _csv(wb, s, name, limits))}
    if not files:
        return None
    runs = []
    if "runs" in wb.sheetnames:
        for r, row in enumerate(list(_rows(wb["runs"], "runs", 50))[1:], start=2):
            vals = [_plain(_cell_value(c, "runs", limits), f"{name}: sheet 'runs' row {r}") for c in row[:5]]
            if vals and vals[0] is not None:
                run = str(vals[0])
                if run not in wb.sheetnames or not safe_id(run):
                    raise SubmissionError(f"{name}: sheet 'runs' row {r}: no sheet named {run!r} with the run's data")
                text = _csv(wb, run, name, limits)
                if text is None:
                    raise SubmissionError(f"{name}: sheet {run!r} holds no data")
                files[f"{run}.csv"] = text
                vals = vals + [None] * 5
                runs.append({"name": run, "file": f"{run}.csv", "kind": vals[1],
                             "controller": {"Kp": vals[2], "Ki": vals[3] or 0.0, "Kd": vals[4] or 0.0}})
    return InlineData(files=files, runs=runs)


def read_xlsx(path: Path, *, limits: Limits = DEFAULT_LIMITS) -> Submission:
    """Read an XLSX submission (formulas are reported, never evaluated)."""
    _check_zip(path, limits)
    try:
        wb = load_workbook(path, read_only=True, data_only=False)
    except Exception as exc:  # openpyxl raises many types on corrupt files
        raise SubmissionError(f"{path.name}: cannot open the workbook ({type(exc).__name__})") from None
    try:
        try:
            missing = [s for s in ("info", "students", "answers") if s not in wb.sheetnames]
            if missing:
                raise SubmissionError(f"{path.name}: missing sheet(s) {', '.join(missing)} (use 'grader template' for the layout)")
            info, info_notes = _info(wb, path.name, limits)
            sid = str(info.get("submission_id") or "").strip()
            if not safe_id(sid):
                raise SubmissionError(f"{path.name}: sheet 'info': submission_id {sid[:64]!r} must be 1-64 letters, digits, _ . - starting with a letter or digit")
            answers = _answers(wb, path.name, limits)
            if "poles" in wb.sheetnames and answers.get("closed_loop_poles") is None:
                answers["closed_loop_poles"] = _poles(wb, limits)
            answers, notes = canonical_answers(answers)
            return Submission(sid, path, _students(wb, path.name, limits), str(info.get("station") or "default")[:64],
                              answers, _data(wb, path.name, limits), (*info_notes, *notes))
        except SubmissionError as exc:
            msg = str(exc)
            raise SubmissionError(msg if msg.startswith(f"{path.name}:") else f"{path.name}: {msg}") from None
        except (ET.ParseError, KeyError, ValueError, zipfile.BadZipFile, OSError, EOFError) as exc:
            # read-only mode parses sheets lazily: malformed XML surfaces only while reading
            raise SubmissionError(f"{path.name}: cannot read the workbook ({type(exc).__name__}); "
                                  "save it again from Excel or use 'grader template'") from None
    finally:
        wb.close()


NOT_REACHABLE_HINT = "; if your rig has no such value, write 'not reachable' (or 'none', 'n/a')"
NOT_IDENTIFIABLE_HINT = "; if your instability run shows no growing oscillation, write 'not identifiable'"


def _unit_hint(item: str, gain_unit: str) -> str:
    spec = ITEMS[item]
    if spec.kind == "expression":
        return "(expression)"
    unit = spec.unit or ("" if gain_unit == "dimensionless" else gain_unit)
    return unit.replace("**", "^") or "(none)"


def _answer_rows(items: list[str], gain_unit: str) -> list[tuple[str, str, str, str]]:
    """(label, expected unit, description, kind) of each answer row; poles have their own sheet."""
    rows = []
    for item in items:
        spec = ITEMS[item]
        if spec.kind == "design":
            rows += [(f"{item}.{p}", _design_hint(p, gain_unit), spec.description, spec.kind) for p in DESIGN_PARTS[item]]
        elif spec.kind != "poles":
            tail = (NOT_REACHABLE_HINT if item in MAY_BE_NOT_REACHABLE else
                    NOT_IDENTIFIABLE_HINT if item in MAY_BE_NOT_IDENTIFIABLE else "")
            rows.append((item, _unit_hint(item, gain_unit), spec.description + tail, spec.kind))
    return rows


def _answers_sheet(wb: Workbook, items: list[str], gain_unit: str) -> None:
    ans = wb.create_sheet("answers")
    ans.append(("item", "value", "unit", "expected unit", "description"))
    numbers = DataValidation(type="decimal", operator="between", formula1="-1E+300", formula2="1E+300",
                             errorStyle="warning", error="Type a number; put its unit in column C. (A prediction your "
                             "rig does not have: type 'not reachable'.)", showErrorMessage=True)
    ans.add_data_validation(numbers)
    for label, unit, description, kind in _answer_rows(items, gain_unit):
        ans.append((label, None, None, unit, description))
        r = ans.max_row
        if not unit.startswith("("):
            offer = DataValidation(type="list", formula1=f'"{unit}"', errorStyle="warning", allow_blank=True,
                                   showErrorMessage=False)
            ans.add_data_validation(offer)
            offer.add(f"C{r}")
        if kind in ("quantity", "design"):
            numbers.add(f"B{r}")


def build_template(items: list[str], *, station: str, gain_unit: str) -> Workbook:
    """The submission workbook for ``items`` (canonical names)."""
    wb = Workbook()
    ws = wb.active
    ws.title = "info"
    for row in (("field", "value"), ("submission_id", "group-01"), ("station", station)):
        ws.append(row)
    wb.create_sheet("students").append(STUDENT_FIELDS)
    _answers_sheet(wb, items, gain_unit)
    if "closed_loop_poles" in items:
        wb.create_sheet("poles").append(("Kp", "Ki", "Kd", "real [1/s]", "imag [1/s]"))
    for sheet, header in DATA_SHEETS.items():
        wb.create_sheet(sheet).append(header)
    wb.create_sheet("runs").append(("name", "kind", "Kp", "Ki", "Kd"))
    for ws in wb.worksheets:
        for col in ("A", "B", "C", "D", "E"):
            ws.column_dimensions[col].width = 22 if col != "E" else 70
    return wb


def _design_hint(part: str, gain_unit: str) -> str:
    units = {"Kp": gain_unit, "Ki": "1/s", "Kd": "s", "overshoot": "%", "ramp_error": "in"}
    base = "" if gain_unit == "dimensionless" else f"{gain_unit}*"
    u = units[part] if part in ("Kp", "overshoot", "ramp_error") else base + units[part]
    return u.replace("dimensionless", "(none)")
