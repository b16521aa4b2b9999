"""The survey mapping: which column of which form holds which lab × statement.

Our own template's column names are derived from the ids (``{lab}.{statement}``,
``{lab}.did_lab``, ``overall.{id}``, ``hours_per_week``, ``most_useful``); the
mapping file only says where a Qualtrics or Google Forms export keeps them.
A lab's ``items`` pattern may use ``{statement}`` (the id), ``{n}`` (its
1-based position) and ``{text}`` (the statement text).
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Literal

import yaml
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    field_validator,
    model_validator,
)

from grader import untrusted
from grader.assess.likert import Scale
from grader.errors import AssessmentError

Form = Literal["template", "qualtrics", "google"]
FORM_NAMES: dict[str, str] = {
    "template": "grader template",
    "qualtrics": "Qualtrics export",
    "google": "Google Forms export",
}
Kind = Literal["rating", "did_lab", "overall", "hours", "most_useful"]
_ID = r"^[a-z][a-z0-9_]*$"
DEFAULT_MAPPING = "survey_mapping_default.yaml"


class _Frozen(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


class Columns(_Frozen):
    """The header of one field in each export form (``None``: not in that form)."""

    qualtrics: str | None = None
    google: str | None = None


class LabColumns(_Frozen):
    """Where one lab's answers are in one export form."""

    did_lab: str | None = None
    items: str

    @field_validator("items")
    @classmethod
    def _known_placeholders(cls, pattern: str) -> str:
        try:
            pattern.format(statement="", n=1, text="")
        except (KeyError, IndexError, ValueError) as exc:
            raise ValueError(f"pattern {pattern!r} may use only {{statement}}, {{n}}, {{text}}") from exc
        return pattern


class Statement(_Frozen):
    id: str = Field(pattern=_ID)
    label: str
    text: str


class Lab(_Frozen):
    id: str = Field(pattern=_ID)
    name: str
    mentions: tuple[str, ...] = ()
    qualtrics: LabColumns | None = None
    google: LabColumns | None = None


class OverallStatement(Statement):
    columns: Columns = Columns()


class SurveyMapping(_Frozen):
    """The whole mapping file."""

    scale: Scale
    statements: tuple[Statement, ...] = Field(min_length=1)
    labs: tuple[Lab, ...] = Field(min_length=2)
    overall: tuple[OverallStatement, ...] = ()
    hours: Columns | None = Columns()
    most_useful: Columns | None = Columns()

    @model_validator(mode="after")
    def _unique_ids(self) -> SurveyMapping:
        for what, ids in (
            ("statement", [s.id for s in self.statements]),
            ("lab", [lab.id for lab in self.labs]),
            ("overall statement", [o.id for o in self.overall]),
        ):
            duplicates = sorted({i for i in ids if ids.count(i) > 1})
            if duplicates:
                raise ValueError(f"duplicate {what} id {duplicates[0]!r}")
        return self

    def lab(self, lab_id: str) -> Lab:
        return next(lab for lab in self.labs if lab.id == lab_id)

    def statement(self, statement_id: str) -> Statement:
        return next(s for s in self.statements if s.id == statement_id)

    def fields(self, form: Form) -> list[ColumnSpec]:
        """Every field this mapping expects in a file of the given form."""
        out: list[ColumnSpec] = []
        for lab in self.labs:
            out.extend(_lab_fields(self, lab, form))
        for item in self.overall:
            header = f"overall.{item.id}" if form == "template" else getattr(item.columns, form)
            out.append(_field("overall", header, f"Overall / {item.label}", form, statement=item.id))
        singles: tuple[tuple[Kind, Columns | None, str], ...] = (
            ("hours", self.hours, "hours_per_week"),
            ("most_useful", self.most_useful, "most_useful"),
        )
        for kind, spec, template in singles:
            if spec is not None:
                header = template if form == "template" else getattr(spec, form)
                out.append(_field(kind, header, kind.replace("_", " "), form))
        return out


@dataclass(frozen=True)
class ColumnSpec:
    """One expected column: what it holds and its header in the form at hand."""

    kind: Kind
    header: str
    description: str
    lab: str | None = None
    statement: str | None = None


def _field(kind: Kind, header: str | None, description: str, form: Form, **ids: str) -> ColumnSpec:
    if header is None:
        raise AssessmentError(
            f"the survey mapping gives no {FORM_NAMES[form]} column for {description}"
        )
    return ColumnSpec(kind=kind, header=header, description=description, **ids)


def _lab_fields(mapping: SurveyMapping, lab: Lab, form: Form) -> list[ColumnSpec]:
    if form == "template":
        did, pattern = f"{lab.id}.did_lab", f"{lab.id}.{{statement}}"
    else:
        columns = getattr(lab, form)
        if columns is None:
            raise AssessmentError(
                f"the survey mapping gives no {FORM_NAMES[form]} columns for the {lab.name} lab"
            )
        did, pattern = columns.did_lab, columns.items
    out: list[ColumnSpec] = []
    if did is not None:
        out.append(_field("did_lab", did, f"{lab.name} / did this lab", form, lab=lab.id))
    for n, stmt in enumerate(mapping.statements, start=1):
        header = pattern.format(statement=stmt.id, n=n, text=stmt.text)
        desc = f"{lab.name} / {stmt.label}"
        out.append(_field("rating", header, desc, form, lab=lab.id, statement=stmt.id))
    return out


def load_mapping(path: Path | None = None) -> SurveyMapping:
    """Load a mapping file, or the shipped default for the paper's form."""
    if path is None:
        text = resources.files("grader").joinpath("data", DEFAULT_MAPPING).read_text("utf-8")
        name = DEFAULT_MAPPING
    else:
        name = Path(path).name
        try:
            text = Path(path).read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise AssessmentError(f"{name}: cannot read the mapping file ({exc})") from exc
    try:
        data = untrusted.load_yaml(text)
    except yaml.YAMLError as exc:
        raise AssessmentError(f"{name}: not valid YAML ({' '.join(str(exc).split())})") from exc
    try:
        return SurveyMapping.model_validate(data)
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(part) for part in first["loc"]) or "top level"
        raise AssessmentError(f"{name}: {where}: {first['msg']}") from exc
