"""JSON and YAML text from users (submissions, dataset manifests), parsed with bounds: no YAML aliases (a
billion laughs expands ten levels of ten aliases into 10¹⁰ values), at most :data:`MAX_YAML_EVENTS` YAML
events and :data:`MAX_DEPTH` levels, and nesting or numbers Python cannot read refused. Every refusal is a
:class:`~grader.errors.GraderError` whose one-line message names the file; callers re-raise it as their own.

Plain YAML scalars are read as YAML 1.2's core schema reads them (:class:`CoreLoader`), not as PyYAML's YAML 1.1:
``1:30`` is text, not 90 (base 60); ``010`` is 10, not 8 (octal); ``1_000``, ``yes``, ``no``, ``on``, ``off``,
``2024-05-01`` and ``=`` are text; ``1e5`` is a number.

A key given twice in one object or mapping is refused (:class:`DuplicateKey`): JSON parsers and PyYAML keep the last
one without a word, so ``{"Kq": "1 in^3/s/mA", "Kq": "0.04 in^3/s/mA"}`` would be graded on the second answer."""

from __future__ import annotations

import json
import math
import re
from typing import Any

import yaml

from grader.errors import GraderError

#: Most YAML events (scalars, starts and ends of mappings and sequences) a document may hold.
MAX_YAML_EVENTS = 50_000
#: Deepest nesting of YAML mappings and sequences (a submission or manifest needs four).
MAX_DEPTH = 64

_BOOL, _INT, _FLOAT, _NULL, _MERGE = (f"tag:yaml.org,2002:{t}" for t in ("bool", "int", "float", "null", "merge"))
#: YAML 1.2 core schema: integers, finite floats, and infinities and NaN.
_INT_RE = re.compile(r"[-+]?[0-9]+|0o[0-7]+|0x[0-9a-fA-F]+")
_FLOAT_RE = re.compile(r"[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?")
_SPECIAL_RE = re.compile(r"([-+]?)\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN)")
#: What PyYAML's constructors raise on text their (explicit) tag cannot hold: '!!float' on nothing, '!!bool maybe'.
_UNREADABLE = (ValueError, IndexError, KeyError, AttributeError, TypeError, OverflowError)
_WHAT = {"int": "an integer", "float": "a number", "bool": "true or false", "timestamp": "a date"}
_TOO_LONG = "a number is too long (write it with fewer digits)"


class DuplicateKey(GraderError):
    """A JSON object or YAML mapping that gives one key twice."""


def unique_object(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """``json.loads``' ``object_pairs_hook``: the object as a dict, refusing a key given twice."""
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise DuplicateKey(f"key {key[:40]!r} appears twice in one object (the second would replace the first)")
        out[key] = value
    return out


class CoreLoader(yaml.SafeLoader):
    """PyYAML's safe loader with YAML 1.2's core schema for booleans, integers and floats. A value its tag cannot
    hold (``!!int 1:30``, ``!!float ''``) is a :class:`yaml.YAMLError` naming it."""

    def construct_object(self, node: yaml.Node, deep: bool = False) -> Any:
        try:
            return super().construct_object(node, deep=deep)
        except _UNREADABLE as exc:
            text, tag = node.value if isinstance(node, yaml.ScalarNode) else "…", node.tag.rsplit(":", 1)[-1]
            what = (_TOO_LONG if isinstance(exc, ValueError) and "digits" in str(exc)  # Python's int-digit limit
                    else f"{text[:40]!r} is not {_WHAT.get(tag, 'a ' + tag)}")
            raise yaml.constructor.ConstructorError(None, None, what, node.start_mark) from None

    def construct_yaml_int(self, node: yaml.ScalarNode) -> int:
        text = self.construct_scalar(node)
        if not _INT_RE.fullmatch(text):
            raise ValueError(text)
        return int(text, 0) if text[:2] in ("0o", "0x") else int(text, 10)

    def construct_yaml_float(self, node: yaml.ScalarNode) -> float:
        text = self.construct_scalar(node)
        if m := _SPECIAL_RE.fullmatch(text):
            return float(f"{m.group(1)}inf") if m.group(1) is not None else math.nan
        if not _FLOAT_RE.fullmatch(text):
            raise ValueError(text)
        return float(text)


CoreLoader.yaml_implicit_resolvers = {  # null and merge (<<) kept; YAML 1.1's timestamps and = are text in 1.2
    first: [(tag, rx) for tag, rx in resolvers if tag in (_NULL, _MERGE)]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()}
CoreLoader.add_implicit_resolver(_BOOL, re.compile(r"^(?:true|True|TRUE|false|False|FALSE)$"), list("tTfF"))
CoreLoader.add_implicit_resolver(_INT, re.compile(f"^(?:{_INT_RE.pattern})$"), list("-+0123456789"))
CoreLoader.add_implicit_resolver(_FLOAT, re.compile(f"^(?:{_FLOAT_RE.pattern}|{_SPECIAL_RE.pattern})$"),
                                 list("-+.0123456789"))
CoreLoader.add_constructor(_INT, CoreLoader.construct_yaml_int)
CoreLoader.add_constructor(_FLOAT, CoreLoader.construct_yaml_float)


def _unique_keys(root: yaml.Node) -> None:
    """Refuse a key written twice in one mapping of the composed document, before anything is constructed (PyYAML
    flattens merged mappings in place while constructing, so a check then would see a merge's override as a second
    key). A merge ``<<`` may be overridden, as YAML allows; keys are compared as written, with their tags."""
    todo, seen = [root], set()
    while todo:
        node = todo.pop()
        if id(node) in seen:
            continue
        seen.add(id(node))
        if isinstance(node, yaml.MappingNode):
            keys: set[tuple[str, str]] = set()
            for key, value in node.value:
                if isinstance(key, yaml.ScalarNode) and key.tag != _MERGE:
                    if (key.tag, key.value) in keys:
                        raise yaml.constructor.ConstructorError(
                            None, None, f"key {key.value[:40]!r} appears twice in one mapping", key.start_mark)
                    keys.add((key.tag, key.value))
                todo += [key, value]
        elif isinstance(node, yaml.SequenceNode):
            todo += node.value


def load_yaml(text: str) -> Any:
    """``text``'s YAML value read as :class:`CoreLoader` reads it, without :func:`parse`'s bounds: for the files
    instructors and lab staff write for themselves (rubrics, stations, survey mappings), so that a scale labelled
    ``No … Yes`` is text there too. A key written twice in one mapping is refused (:func:`_unique_keys`)."""
    loader = CoreLoader(text)  # a SafeLoader: no Python objects
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        _unique_keys(node)
        return loader.construct_document(node)
    finally:
        loader.dispose()


def parse(name: str, text: str, *, as_json: bool, max_yaml_events: int = MAX_YAML_EVENTS) -> Any:
    """The value that ``text`` (from file ``name``) holds, as JSON or as YAML."""
    kind = "JSON" if as_json else "YAML"
    try:
        if as_json:
            return json.loads(text, object_pairs_hook=unique_object)
        depth = 0
        for n, event in enumerate(yaml.parse(text, Loader=CoreLoader)):
            if isinstance(event, yaml.AliasEvent):
                raise GraderError(f"{name}: YAML aliases (*name) are not allowed here")
            if n > max_yaml_events:
                raise GraderError(f"{name}: YAML document too large")
            depth += isinstance(event, yaml.CollectionStartEvent) - isinstance(event, yaml.CollectionEndEvent)
            if depth > MAX_DEPTH:  # the scanner's cost grows with the depth: 200 kB of '[' took minutes
                raise GraderError(f"{name}: YAML nested too deeply")
        return load_yaml(text)
    except json.JSONDecodeError as exc:
        raise GraderError(f"{name}: not valid JSON: {_json_fault(exc)}") from None
    except DuplicateKey as exc:
        raise GraderError(f"{name}: {exc}") from None
    except yaml.YAMLError as exc:
        raise GraderError(f"{name}: not valid YAML: {_yaml_fault(exc)}") from None
    except RecursionError:
        raise GraderError(f"{name}: {kind} nested too deeply") from None
    except ValueError:  # JSON: an integer beyond Python's int-digit limit (YAML says so as a YAMLError)
        raise GraderError(f"{name}: not valid {kind}: {_TOO_LONG}") from None


def _yaml_fault(exc: yaml.YAMLError) -> str:
    """PyYAML's problem and the line it is on ("found unhashable key (line 1)"), rather than only its context
    ("while constructing a mapping")."""
    problem, mark = getattr(exc, "problem", None), getattr(exc, "problem_mark", None)
    if problem:
        return f"{problem}" + (f" (line {mark.line + 1})" if mark is not None and "(line " not in problem else "")
    return str(exc).splitlines()[0] if str(exc) else type(exc).__name__


def _json_fault(exc: json.JSONDecodeError) -> str:
    """The decoder's message and where, or what a person wrote there: a comma after the last item (which YAML,
    Python and JavaScript allow), named where the comma is, when the text without it gets past that point."""
    doc, comma = exc.doc, len(exc.doc[:exc.pos].rstrip()) - 1
    closes = doc[exc.pos:exc.pos + 1] in ("}", "]") and comma >= 0 and doc[comma] == ","
    if closes and _parses_past(doc[:comma] + doc[comma + 1:], comma):
        line, column = doc.count("\n", 0, comma) + 1, comma - doc.rfind("\n", 0, comma)
        return f"a comma after the last item before '{doc[exc.pos]}' at line {line}, column {column} (JSON allows none)"
    return f"{exc.msg} at line {exc.lineno}, column {exc.colno}"


def _parses_past(text: str, pos: int) -> bool:
    """Whether JSON ``text`` parses, or fails only after ``pos`` (a bracket that does not match fails there)."""
    try:
        json.loads(text)
    except json.JSONDecodeError as exc:
        return exc.pos > pos
    except (RecursionError, ValueError):
        return False
    return True
