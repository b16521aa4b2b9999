"""The exception tree of `grader`.

Every error a user can provoke derives from :class:`GraderError` and carries a
one-line, specific message (naming the file, row, column or field at fault).
The CLI prints that message and exits non-zero; no traceback reaches a user.

::

    GraderError
    ├── UnitError          a quantity string pint cannot parse, or of the wrong dimension
    ├── DatasetError       a lab dataset (manifest, CSV) is missing, malformed or inconsistent
    ├── ModelError         the physics cannot be evaluated (e.g. unstable loop where stability is needed)
    ├── IdentificationError  the data do not support an identification step
    ├── KeyFileError       an answer-key file is malformed
    ├── RubricError        a rubric file is malformed (an instructor mistake)
    ├── SubmissionError    a submission cannot be read (becomes feedback, never stops a batch)
    ├── ExpressionError    a submitted expression is rejected by the AST whitelist or limits
    ├── SimulationError    the rig simulator was given an unknown effect or an out-of-range value
    ├── AssessmentError    a survey or exam-score file is malformed
    ├── DiagnosisError     the gap diagnosis cannot run on the given data
    └── OutputPathError    an output path cannot take the file or folder a verb writes

:func:`validation_message` turns a pydantic ``ValidationError`` into such a one-line message.
"""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # pydantic is imported by the modules that validate, not by the CLI's start-up
    from pydantic import ValidationError


class GraderError(Exception):
    """Base class: a user-facing error with a one-line message."""


class UnitError(GraderError):
    """A quantity could not be parsed or has the wrong dimension."""


class DatasetError(GraderError):
    """A lab dataset is missing, malformed or inconsistent."""


class ModelError(GraderError):
    """The linear model cannot be evaluated for the given parameters."""


class IdentificationError(GraderError):
    """The data do not support an identification step."""


class KeyFileError(GraderError):
    """An answer-key file is malformed."""


class RubricError(GraderError):
    """A rubric file is malformed."""


class SubmissionError(GraderError):
    """A submission cannot be read."""


class ExpressionError(GraderError):
    """A submitted expression was rejected."""


class SimulationError(GraderError):
    """The rig simulator was given an unknown effect or an out-of-range value."""


class AssessmentError(GraderError):
    """A survey or exam-score file is malformed."""


class DiagnosisError(GraderError):
    """The gap diagnosis cannot run on the given data."""


class OutputPathError(GraderError):
    """An output path is a folder where a file is expected (or the reverse), or cannot be written."""


#: Plain sentences for pydantic's error types (its own wording is jargon to a student).
_PLAIN = {
    "missing": "is required but missing",
    "extra_forbidden": "is not a field of this file (check the spelling)",
    "list_type": "should be a list, e.g. [a, b], not {kind}",
    "dict_type": "should be a table of name: value pairs, not {kind}",
    "model_type": "should be a table of name: value pairs, not {kind}",
    "string_type": "should be text, not {kind}",
    "float_type": "should be a number, not {kind}",
    "float_parsing": "should be a number, not {kind}",
    "int_type": "should be a whole number, not {kind}",
    "int_parsing": "should be a whole number, not {kind}",
    "bool_type": "should be true or false, not {kind}",
    "too_short": "has too few entries (at least {min_length})",
    "too_long": "has too many entries (at most {max_length})",
    "string_too_short": "is too short (at least {min_length} characters)",
    "string_too_long": "is too long (at most {max_length} characters)",
    "string_pattern_mismatch": "has characters that are not allowed here",
    "literal_error": "should be one of {expected}",
    "enum": "should be one of {expected}",
    "greater_than": "should be greater than {gt}",
    "greater_than_equal": "should be at least {ge}",
    "less_than": "should be less than {lt}",
    "less_than_equal": "should be at most {le}",
}


def _kind(value: object) -> str:
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) > sys.float_info.max:
        return "a number beyond a double's range (1.8e308)"
    return {list: "a list", dict: "a table", str: "text", bool: "true/false", type(None): "nothing"}.get(
        type(value), "a number" if isinstance(value, (int, float)) else type(value).__name__)


def validation_message(source: str, exc: ValidationError) -> str:
    """One plain line for a pydantic ``ValidationError``: ``"<source>: field a.b <what was expected>"``,
    then how many other fields have problems (the alternatives of one field count once)."""
    errors = exc.errors()
    err = errors[0]
    loc = ".".join(str(p) for p in err["loc"]) or "(top level)"
    fields = len({e["loc"] for e in errors}) - 1
    more = f" (and {fields} more field{'s' if fields > 1 else ''} with problems)" if fields else ""
    template = _PLAIN.get(err["type"])
    if template is None:
        return f"{source}: field {loc}: {err['msg'].removeprefix('Value error, ')}{more}"
    return f"{source}: field {loc} " + template.format(kind=_kind(err.get("input")), **err.get("ctx", {})) + more
