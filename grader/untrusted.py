"""JSON and YAML text from users (submissions, dataset manifests), parsed with bounds: no YAML aliases (a
billion laughs expands ten levels of ten aliases into 10¹⁰ values), at most :data:`MAX_YAML_EVENTS` YAML
events and :data:`MAX_DEPTH` levels, and nesting or numbers Python cannot read refused. Every refusal is a
:class:`~grader.errors.GraderError` whose one-line message names the file; callers re-raise it as their own.

Plain YAML scalars are read as YAML 1.2's core schema reads them (:class:`CoreLoader`), not as PyYAML's YAML 1.1:
``1:30`` is text, not 90 (base 60); ``010`` is 10, not 8 (octal); ``1_000``, ``yes``, ``no``, ``on``, ``off``,
``2024-05-01`` and ``=`` are text; ``1e5`` is a number."""

from __future__ import annotations

import json
import re
from typing import Any

import yaml

from grader.errors import GraderError

#: Most YAML events (scalars, starts and ends of mappings and sequences) a document may hold.
MAX_YAML_EVENTS = 50_000
#: Deepest nesting of YAML mappings and sequences (a submission or manifest needs four).
MAX_DEPTH = 64

_BOOL, _INT, _FLOAT, _NULL, _MERGE = (f"tag:yaml.org,2002:{t}" for t in ("bool", "int", "float", "null", "merge"))


class CoreLoader(yaml.SafeLoader):
    """PyYAML's safe loader with YAML 1.2's core schema for booleans, integers and floats."""

    def construct_yaml_int(self, node: yaml.ScalarNode) -> int:
        text = self.construct_scalar(node)
        digits = text.lstrip("+-")
        try:
            value = int(digits, 0) if digits[:2] in ("0o", "0x") else int(digits, 10)
        except ValueError:
            if digits.isdigit():  # beyond Python's int-digit limit
                raise
            raise yaml.constructor.ConstructorError(None, None, f"{text[:40]!r} is not an integer", node.start_mark) from None
        return -value if text.startswith("-") else value

    def construct_yaml_float(self, node: yaml.ScalarNode) -> float:
        try:
            return super().construct_yaml_float(node)
        except ValueError:  # an explicit !!float on text
            raise yaml.constructor.ConstructorError(None, None, f"{self.construct_scalar(node)[:40]!r} is not a number",
                                                    node.start_mark) from None


CoreLoader.yaml_implicit_resolvers = {  # null and merge (<<) kept; YAML 1.1's timestamps and = are text in 1.2
    first: [(tag, rx) for tag, rx in resolvers if tag in (_NULL, _MERGE)]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()}
CoreLoader.add_implicit_resolver(_BOOL, re.compile(r"^(?:true|True|TRUE|false|False|FALSE)$"), list("tTfF"))
CoreLoader.add_implicit_resolver(_INT, re.compile(r"^(?:[-+]?[0-9]+|0o[0-7]+|0x[0-9a-fA-F]+)$"), list("-+0123456789"))
CoreLoader.add_implicit_resolver(
    _FLOAT, re.compile(r"^(?:[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$"),
    list("-+.0123456789"))
CoreLoader.add_constructor(_INT, CoreLoader.construct_yaml_int)
CoreLoader.add_constructor(_FLOAT, CoreLoader.construct_yaml_float)


def load_yaml(text: str) -> Any:
    """``text``'s YAML value read as :class:`CoreLoader` reads it, without :func:`parse`'s bounds: for the files
    instructors and lab staff write for themselves (rubrics, stations, survey mappings), so that a scale labelled
    ``No … Yes`` is text there too."""
    return yaml.load(text, Loader=CoreLoader)  # a SafeLoader: no Python objects

def parse(name: str, text: str, *, as_json: bool, max_yaml_events: int = MAX_YAML_EVENTS) -> Any:
    """The value that ``text`` (from file ``name``) holds, as JSON or as YAML."""
    kind = "JSON" if as_json else "YAML"
    try:
        if as_json:
            return json.loads(text)
        depth = 0
        for n, event in enumerate(yaml.parse(text, Loader=CoreLoader)):
            if isinstance(event, yaml.AliasEvent):
                raise GraderError(f"{name}: YAML aliases (*name) are not allowed here")
            if n > max_yaml_events:
                raise GraderError(f"{name}: YAML document too large")
            depth += isinstance(event, yaml.CollectionStartEvent) - isinstance(event, yaml.CollectionEndEvent)
            if depth > MAX_DEPTH:  # the scanner's cost grows with the depth: 200 kB of '[' took minutes
                raise GraderError(f"{name}: YAML nested too deeply")
        return yaml.load(text, Loader=CoreLoader)  # a SafeLoader: no Python objects
    except json.JSONDecodeError as exc:
        raise GraderError(f"{name}: not valid JSON: {_json_fault(exc)}") from None
    except yaml.YAMLError as exc:
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise GraderError(f"{name}: not valid YAML: {first}") from None
    except RecursionError:
        raise GraderError(f"{name}: {kind} nested too deeply") from None
    except ValueError:  # an integer beyond Python's int-digit limit
        raise GraderError(f"{name}: not valid {kind}: a number is too long (write it with fewer digits)") from None


def _json_fault(exc: json.JSONDecodeError) -> str:
    """The decoder's message and where, or what a person wrote there: a comma after the last item (which YAML,
    Python and JavaScript allow), named where the comma is."""
    comma = len(exc.doc[:exc.pos].rstrip()) - 1
    if exc.doc[exc.pos:exc.pos + 1] in ("}", "]") and comma >= 0 and exc.doc[comma] == ",":
        line, column = exc.doc.count("\n", 0, comma) + 1, comma - exc.doc.rfind("\n", 0, comma)
        return f"a comma after the last item before '{exc.doc[exc.pos]}' at line {line}, column {column} (JSON allows none)"
    return f"{exc.msg} at line {exc.lineno}, column {exc.colno}"
