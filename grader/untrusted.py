"""JSON and YAML text from users (submissions, dataset manifests), parsed with bounds: no YAML aliases (a
billion laughs expands ten levels of ten aliases into 10¹⁰ values), at most :data:`MAX_YAML_EVENTS` YAML
events and :data:`MAX_DEPTH` levels, and nesting or numbers Python cannot read refused. Every refusal is a
:class:`~grader.errors.GraderError` whose one-line message names the file; callers re-raise it as their own."""

from __future__ import annotations

import json
from typing import Any

import yaml

from grader.errors import GraderError

#: Most YAML events (scalars, starts and ends of mappings and sequences) a document may hold.
MAX_YAML_EVENTS = 50_000
#: Deepest nesting of YAML mappings and sequences (a submission or manifest needs four).
MAX_DEPTH = 64


def parse(name: str, text: str, *, as_json: bool, max_yaml_events: int = MAX_YAML_EVENTS) -> Any:
    """The value that ``text`` (from file ``name``) holds, as JSON or as YAML."""
    kind = "JSON" if as_json else "YAML"
    try:
        if as_json:
            return json.loads(text)
        depth = 0
        for n, event in enumerate(yaml.parse(text, Loader=yaml.SafeLoader)):
            if isinstance(event, yaml.AliasEvent):
                raise GraderError(f"{name}: YAML aliases (*name) are not allowed here")
            if n > max_yaml_events:
                raise GraderError(f"{name}: YAML document too large")
            depth += isinstance(event, yaml.CollectionStartEvent) - isinstance(event, yaml.CollectionEndEvent)
            if depth > MAX_DEPTH:  # the scanner's cost grows with the depth: 200 kB of '[' took minutes
                raise GraderError(f"{name}: YAML nested too deeply")
        return yaml.safe_load(text)
    except json.JSONDecodeError as exc:
        raise GraderError(f"{name}: not valid JSON: {exc.msg} at line {exc.lineno}, column {exc.colno}") from None
    except yaml.YAMLError as exc:
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise GraderError(f"{name}: not valid YAML: {first}") from None
    except RecursionError:
        raise GraderError(f"{name}: {kind} nested too deeply") from None
    except ValueError:  # an integer beyond Python's int-digit limit
        raise GraderError(f"{name}: not valid {kind}: a number is too long (write it with fewer digits)") from None
