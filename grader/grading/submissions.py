"""Submissions: the schema, and the JSON / YAML readers (XLSX in :mod:`grader.grading.xlsx_io`).

A submission carries ``submission_id``, ``students`` (name, sis_user_id, login_id,
section, optional Canvas ``id``), ``station``, optionally ``data`` (its group's own
lab dataset: a folder next to the submission file, or sheets of the XLSX) and
``answers`` (canonical item -> value). Files are untrusted: sizes are capped before
reading, YAML aliases are refused, and every problem is a one-line
:class:`~grader.errors.SubmissionError` naming the file and field.
"""

from __future__ import annotations

import difflib
import re
import unicodedata
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from grader import untrusted
from grader.errors import GraderError, SubmissionError, validation_message
from grader.grading.items import ITEMS
from grader.grading.limits import DEFAULT_LIMITS, Limits
from grader.grading.results import Student

SAFE_ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.\-]{0,63}$")  # use with fullmatch (``$`` alone allows a trailing newline)


def safe_id(text: str) -> bool:
    """True for a submission id that is safe as a file name: a letter or digit, then up to 63 of
    letters, digits, ``_ . -``."""
    return SAFE_ID.fullmatch(text) is not None
SUFFIXES = (".json", ".yaml", ".yml", ".xlsx")


class StudentModel(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    name: str = Field(min_length=1, max_length=200)
    sis_user_id: str = Field(default="", max_length=100)
    login_id: str = Field(default="", max_length=100)
    section: str = Field(default="", max_length=100)
    id: str = Field(default="", max_length=100)

    @field_validator("sis_user_id", "login_id", "section", "id", mode="before")
    @classmethod
    def _text(cls, v: Any) -> Any:
        return str(v) if isinstance(v, int) and not isinstance(v, bool) else ("" if v is None else v)

    @field_validator("name", "sis_user_id", "login_id", "section", "id")
    @classmethod
    def _printable(cls, v: str) -> str:
        """Names and ids go to the LMS and the gradebook: a tab or line break pasted in reads as a space; another
        control character is a typing or export slip, refused."""
        if any(c in v for c in "\t\n\r"):
            v = re.sub(r"\s*[\t\n\r]+\s*", " ", v).strip()
            if not v:
                raise ValueError("holds only blanks")
        bad = next((c for c in v if unicodedata.category(c) == "Cc"), None)
        if bad is not None:
            raise ValueError(f"contains a control character (U+{ord(bad):04X})")
        return v


class SubmissionModel(BaseModel):
    """The top level of a JSON/YAML submission."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    submission_id: str = Field(max_length=64)
    students: list[StudentModel] = Field(min_length=1, max_length=10)
    station: str = Field(default="default", max_length=64)
    data: str | None = Field(default=None, max_length=255)
    answers: dict[str, Any] = Field(default_factory=dict, max_length=64)

    @field_validator("submission_id")
    @classmethod
    def _id(cls, v: str) -> str:
        if not safe_id(v):
            raise ValueError(f"{v[:64]!r} must be 1-64 letters, digits, _ . - starting with a letter or digit, "
                             "e.g. group-07")
        return v


@dataclass(frozen=True)
class InlineData:
    """A group's dataset given as sheets: ``files`` maps file name -> CSV text; ``runs`` the run specs."""

    files: dict[str, str]
    runs: list[dict[str, Any]]


@dataclass(frozen=True)
class InvalidAnswer:
    """An answer known to be unreadable before checking (e.g. an XLSX formula cell)."""

    reason: str


@dataclass(frozen=True)
class Submission:
    """A read submission; ``data`` is the group's dataset folder, sheets, or None (use the station's)."""

    submission_id: str
    source: Path
    students: tuple[Student, ...]
    station: str
    answers: dict[str, Any]
    data: Path | InlineData | None = None
    notes: tuple[str, ...] = field(default_factory=tuple)


def fallback_id(path: Path) -> str:
    """A safe submission id from a file name (for files that cannot be read)."""
    stem = re.sub(r"[^A-Za-z0-9_.\-]", "_", path.stem)[:64].lstrip("_.-").rstrip(".") or "submission"
    return stem



def _load_text(path: Path, limits: Limits) -> Any:
    size = path.stat().st_size
    if size > limits.max_text_bytes:
        raise SubmissionError(f"{path.name}: file is {size / 1e6:.1f} MB; submissions are limited to "
                              f"{limits.max_text_bytes / 1e6:g} MB")
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise SubmissionError(f"{path.name}: not UTF-8 text") from None
    try:
        return untrusted.parse(path.name, text, as_json=path.suffix == ".json", max_yaml_events=limits.max_yaml_events)
    except GraderError as exc:
        raise SubmissionError(str(exc)) from None


def resolve_data_dir(path: Path, data: str) -> Path:
    """The group's dataset folder, which must lie inside the submission's own folder."""
    base = path.parent.resolve()
    if Path(data).is_absolute() or ".." in Path(data).parts:
        raise SubmissionError(f"{path.name}: field data: {data!r} must be a folder next to the submission "
                              "(no '..', not absolute)")
    target = (base / data).resolve()
    if not target.is_relative_to(base):
        raise SubmissionError(f"{path.name}: field data: {data!r} is a link that leads out of the submission's folder")
    if not target.is_dir():
        raise SubmissionError(f"{path.name}: field data: folder {data!r} not found next to the submission")
    return target


def canonical_answers(answers: dict[str, Any]) -> tuple[dict[str, Any], tuple[str, ...]]:
    """Answers keyed by canonical item names, and notes on the names changed or ignored.

    A name that differs from an item only in letter case (``kq``) is read as that item unless
    the item is also given; any other unknown name is ignored, with a "did you mean" hint."""
    by_lower = {i.lower(): i for i in ITEMS}
    out: dict[str, Any] = {}
    notes = []
    for k, v in answers.items():
        key = str(k)
        item = key if key in ITEMS else by_lower.get(key.lower())
        if item is not None and (item == key or item not in answers):
            out[item] = v
            if item != key:
                notes.append(f"answer {key[:40]!r} was read as {item!r} (write item names as {item!r})")
            continue
        close = [item] if item else difflib.get_close_matches(key, list(ITEMS), n=1)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        notes.append(f"answer {key[:40]!r} is not an item of this lab and was ignored{hint}")
    return out, tuple(notes)


def from_mapping(path: Path, raw: Any) -> Submission:
    """Validate a parsed JSON/YAML document."""
    if not isinstance(raw, dict):
        raise SubmissionError(f"{path.name}: must hold a mapping (object) at the top level, got {type(raw).__name__}")
    try:
        m = SubmissionModel.model_validate(raw)
    except ValidationError as exc:
        raise SubmissionError(validation_message(path.name, exc)) from None
    students = tuple(Student(s.name, s.sis_user_id, s.login_id, s.section, s.id) for s in m.students)
    data = resolve_data_dir(path, m.data) if m.data else None
    answers, notes = canonical_answers(m.answers)
    return Submission(m.submission_id, path, students, m.station, answers, data, notes)


def read_submission(path: str | Path, *, limits: Limits = DEFAULT_LIMITS) -> Submission:
    """Read a JSON, YAML or XLSX submission; raises SubmissionError naming the file and field."""
    path = Path(path)
    if not path.is_file():
        raise SubmissionError(f"{path}: " + ("is a folder; give one submission file" if path.is_dir() else
                                             "not a regular file" if path.exists() else "file not found"))
    if path.suffix.lower() not in SUFFIXES:
        raise SubmissionError(f"{path.name}: unknown submission type (use {', '.join(SUFFIXES)})")
    if path.suffix.lower() == ".xlsx":
        from grader.grading.xlsx_io import read_xlsx

        return read_xlsx(path, limits=limits)
    return from_mapping(path, _load_text(path, limits))


def students_hint(path: Path, *, limits: Limits = DEFAULT_LIMITS) -> tuple[Student, ...]:
    """Best-effort students of a submission that failed validation (for its gradebook row)."""
    try:
        raw = _load_text(path, limits) if path.suffix.lower() in (".json", ".yaml", ".yml") else None
        items = raw.get("students") if isinstance(raw, dict) else None
        return tuple(Student(**StudentModel.model_validate(s).model_dump(exclude={"id"}), canvas_id=str(s.get("id", "")))
                     for s in items) if isinstance(items, list) and len(items) <= 10 else ()
    except (SubmissionError, ValidationError, TypeError, AttributeError, OSError):
        return ()
