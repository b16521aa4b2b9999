"""The bounded JSON/YAML reader of users' text (manifests, submissions): YAML 1.2's core schema for plain
scalars, not PyYAML's YAML 1.1 (base-60 times, octal, yes/no booleans)."""

from __future__ import annotations

import json
import math

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from grader.errors import GraderError
from grader.untrusted import load_yaml, parse

SCALARS = [
    ("1:30", "1:30"),  # YAML 1.1: 90 (base 60)
    ("010", 10),  # YAML 1.1: 8 (octal)
    ("007", 7),
    ("0o17", 15),
    ("0x1A", 26),
    ("1_000", "1_000"),  # YAML 1.1: 1000
    ("yes", "yes"),
    ("no", "no"),
    ("on", "on"),
    ("Off", "Off"),
    ("y", "y"),
    ("true", True),
    ("False", False),
    ("1e5", 100000.0),  # PyYAML: text (its floats need a dot)
    ("-.5", -0.5),
    ("3.", 3.0),
    ("+3.5", 3.5),
    ("-12", -12),
    ("1.5e-3", 0.0015),
    ("~", None),
    ("null", None),
    ("'010'", "010"),
    ("0b11", "0b11"),
    ("-0x10", "-0x10"),
    ("!!int 0x1F", 31),
    ("!!float 10", 10.0),
    (".e5", ".e5"),
    ("2024-05-01", "2024-05-01"),  # YAML 1.1: a date
    ("2001-12-14t21:59:43.10-05:00", "2001-12-14t21:59:43.10-05:00"),
    ("=", "="),  # PyYAML: a tag it cannot construct
]


@pytest.mark.parametrize(("text", "value"), SCALARS, ids=[s[0] for s in SCALARS])
def test_plain_scalars_read_as_yaml_1_2_core(text: str, value: object) -> None:
    got = parse("m.yaml", f"x: {text}\n", as_json=False)["x"]
    assert got == value and type(got) is type(value)


def test_infinity_and_nan_are_floats() -> None:
    got = parse("m.yaml", "a: .inf\nb: -.Inf\nc: .nan\n", as_json=False)
    assert got["a"] == math.inf and got["b"] == -math.inf and math.isnan(got["c"])


@pytest.mark.parametrize(("text", "words"), [
    ("x: !!int 1:30", "m.yaml: not valid YAML: '1:30' is not an integer"),
    ("x: !!float abc", "m.yaml: not valid YAML: 'abc' is not a number"),
    ("x: " + "9" * 5000, "m.yaml: not valid YAML: a number is too long"),
    ("x: !!int 1_000", "m.yaml: not valid YAML: '1_000' is not an integer"),  # int() would read 1000
    ("x: !!int --5", "m.yaml: not valid YAML: '--5' is not an integer"),
    ("x: !!float 1:30", "m.yaml: not valid YAML: '1:30' is not a number"),  # PyYAML: 90.0
    # PyYAML's own constructors raised IndexError, KeyError and AttributeError on these: tracebacks
    ("x: !!float ''", "m.yaml: not valid YAML: '' is not a number"),
    ("x: !!bool maybe", "m.yaml: not valid YAML: 'maybe' is not true or false"),
    ("x: !!timestamp x", "m.yaml: not valid YAML: 'x' is not a date"),
])
def test_scalars_that_are_no_number_are_one_line_errors(text: str, words: str) -> None:
    with pytest.raises(GraderError, match="^" + words.replace("(", r"\(")):
        parse("m.yaml", text, as_json=False)


@pytest.mark.parametrize(("text", "message"), [
    ('{"Kp": 10,\n}',
     "m.json: not valid JSON: a comma after the last item before '}' at line 1, column 10 (JSON allows none)"),
    ('{"runs": [1, 2,],\n "x": 1}',
     "m.json: not valid JSON: a comma after the last item before ']' at line 1, column 15 (JSON allows none)"),
    ('{"Kp" 10}', "m.json: not valid JSON: Expecting ':' delimiter at line 1, column 7"),
    ('[,]', "m.json: not valid JSON: Expecting value at line 1, column 2"),
    ('{"a": [1,}', "m.json: not valid JSON: Expecting value at line 1, column 10"),  # a bracket that does not match
])
def test_json_faults_are_named_where_they_are(text: str, message: str) -> None:
    with pytest.raises(GraderError) as exc:
        parse("m.json", text, as_json=True)
    assert str(exc.value) == message


#: Text YAML may hold as it is (its printable characters: no control characters or DEL).
TEXT = st.text(st.characters(categories=("L", "N", "P", "S", "Zs")), max_size=20)
JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers(-10**30, 10**30) | st.floats(allow_nan=False, allow_infinity=False) | TEXT,
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(TEXT, inner, max_size=4),
    max_leaves=20)


@settings(max_examples=200, deadline=None)
@given(JSON_VALUES)
def test_json_text_reads_the_same_as_yaml(value: object) -> None:
    """JSON is YAML 1.2: a submission or manifest saved as JSON means the same read as YAML."""
    text = json.dumps(value, ensure_ascii=False)
    assert parse("m.yaml", text, as_json=False) == parse("m.json", text, as_json=True) == value


@pytest.mark.parametrize("text", ["x: " + "9" * 5000, "x: !!bool maybe", "x: !!float ''"])
def test_the_files_instructors_write_get_a_yaml_error_not_a_traceback(text: str) -> None:
    """Rubrics, stations and survey mappings (:func:`load_yaml`) turn YAML errors into their own one-line errors;
    a ValueError (Python's int-digit limit) or KeyError escaped them as a traceback."""
    with pytest.raises(yaml.YAMLError):
        load_yaml(text)


@pytest.mark.parametrize(("text", "as_json", "message"), [
    ('{"answers": {"Kq": "1 in^3/s/mA", "Kq": "0.04 in^3/s/mA"}}', True,
     "s.json: key 'Kq' appears twice in one object (the second would replace the first)"),
    ("answers:\n  Kq: 1 in^3/s/mA\n  Kq: 0.04 in^3/s/mA\n", False,
     "s.json: not valid YAML: key 'Kq' appears twice in one mapping (line 3)"),
])
def test_a_key_given_twice_is_refused_not_replaced(text: str, as_json: bool, message: str) -> None:
    """JSON parsers and PyYAML keep the last of two equal keys without a word: the first answer would vanish."""
    with pytest.raises(GraderError) as exc:
        parse("s.json", text, as_json=as_json)
    assert str(exc.value) == message


def test_equal_keys_in_different_mappings_and_a_merge_override_are_fine() -> None:
    assert parse("m", '{"a": {"b": 1}, "c": {"b": 2}}', as_json=True) == {"a": {"b": 1}, "c": {"b": 2}}
    assert load_yaml("x: {c: 1}\ny:\n  <<: {c: 1}\n  c: 2\n") == {"x": {"c": 1}, "y": {"c": 2}}
    # a merged mapping that overrides its own merge, merged again: PyYAML flattens it in place while constructing,
    # so only a check of the composed document (not of the constructed mappings) leaves it alone
    nested = "base: &base {a: 1}\ngroups:\n  - &g1\n    <<: *base\n    a: 2\nx:\n  <<: *g1\n"
    assert load_yaml(nested) == yaml.safe_load(nested)


@pytest.mark.parametrize(("text", "message"), [
    ("? [a, b]\n: 1\n", "m.yaml: not valid YAML: found unhashable key (line 1)"),
    ("a: [1, 2\n", "m.yaml: not valid YAML: expected ',' or ']', but got '<stream end>' (line 2)"),
])
def test_yaml_faults_name_the_problem_and_its_line(text: str, message: str) -> None:
    """Not only PyYAML's context ("while constructing a mapping", "while parsing a flow sequence")."""
    with pytest.raises(GraderError) as exc:
        parse("m.yaml", text, as_json=False)
    assert str(exc.value) == message
