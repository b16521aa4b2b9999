"""The dataset format: round trip, unit conversion, and one clear error per kind of bad input."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from grader.cli import main
from grader.datasets import load
from grader.errors import DatasetError


@pytest.fixture
def ds(tmp_path: Path, linear_dataset: Path) -> Path:
    out = tmp_path / "ds"
    shutil.copytree(linear_dataset, out)
    return out


def _edit_manifest(ds: Path, **changes: object) -> None:
    m = json.loads((ds / "manifest.json").read_text())
    m.update(changes)
    (ds / "manifest.json").write_text(json.dumps(m))


def test_round_trip_and_units(ds: Path) -> None:
    d = load(ds)
    assert [r.name for r in d.runs] == ["step_kp10", "step_kp25", "step_kp46", "instability", "ramp_p", "ramp_pi"]
    # flow.csv is written in gpm and converted to in³/s on load
    raw = np.loadtxt(ds / "flow.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(d.flow_test["flow"], raw[:, 1] * 231.0 / 60.0)
    assert d.given["M"] == pytest.approx(29 / 386.0886, rel=1e-5)


def test_headers_in_other_units_are_converted(ds: Path) -> None:
    text = (ds / "step_kp10.csv").read_text().splitlines()
    rows = [line.split(",") for line in text[1:]]
    lines = ["t [ms],r [mm],y [mm],u [V]"] + [
        f"{float(a) * 1000:.9g},{float(b) * 25.4:.9g},{float(c) * 25.4:.9g},{d}" for a, b, c, d in rows
    ]
    before = load(ds).runs[0]
    (ds / "step_kp10.csv").write_text("\n".join(lines) + "\n")
    after = load(ds).runs[0]
    np.testing.assert_allclose(after.y, before.y, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(after.t, before.t, rtol=1e-8, atol=1e-12)


def test_hash_is_stable_and_sensitive(ds: Path) -> None:
    h1 = load(ds).inputs_sha256
    assert load(ds).inputs_sha256 == h1
    with (ds / "calibration.csv").open("a") as f:
        f.write("5,9\n")
    assert load(ds).inputs_sha256 != h1


def _replace_header(ds: Path, file: str, header: str) -> None:
    lines = (ds / file).read_text().splitlines()
    (ds / file).write_text("\n".join([header, *lines[1:]]) + "\n")


def _given(ds: Path) -> dict[str, str]:
    return json.loads((ds / "manifest.json").read_text())["given"]


def _yaml_copy(ds: Path, **changes: object) -> None:
    """manifest.yaml beside manifest.json: the JSON's content with ``changes``."""
    m = json.loads((ds / "manifest.json").read_text())
    (ds / "manifest.yaml").write_text(yaml.safe_dump({**m, **changes}))


BAD_CASES = [
    ("wrong unit dimension", lambda d: _replace_header(d, "step_kp10.csv", "t [s],r [in],y [psi],u [V]"),
     ["step_kp10.csv", "'y'"]),
    ("unknown unit", lambda d: _replace_header(d, "calibration.csv", "position [furlongz],voltage [V]"),
     ["calibration.csv", "furlongz"]),
    ("missing column", lambda d: _replace_header(d, "flow.csv", "input [V],flowz [gpm]"), ["flow.csv", "missing column", "flow"]),
    ("bad header cell", lambda d: _replace_header(d, "friction.csv", "speed,force [lbf]"), ["friction.csv", "name [unit]"]),
    ("garbage manifest", lambda d: (d / "manifest.json").write_text("{not json"), ["manifest.json", "not valid JSON"]),
    ("manifest list", lambda d: (d / "manifest.json").write_text("[1, 2]"), ["manifest.json", "mapping"]),
    ("negative weight", lambda d: _edit_manifest(d, given={"weight": "-29 lbf"}), ["manifest.json", "mass must be positive"]),
    ("weight in psi", lambda d: _edit_manifest(d, given={"weight": "29 psi"}), ["given.weight", "psi is a pressure; expected a force"]),
    ("unknown field", lambda d: _edit_manifest(d, colour="red"), ["manifest.json", "colour"]),
    ("unknown run kind", lambda d: _edit_manifest(d, runs=[{"name": "a", "file": "step_kp10.csv", "kind": "sine",
                                                           "controller": {"Kp": 1}}]), ["runs.0.kind"]),
    ("path traversal", lambda d: _edit_manifest(d, calibration="../x.csv"), ["calibration", "plain file name"]),
    ("missing file", lambda d: (d / "ramp_pi.csv").unlink(), ["ramp_pi.csv", "not found"]),
    ("two manifests that differ", lambda d: _yaml_copy(d, station="other"),
     ["manifest.json and manifest.yaml", "say different things (first in 'station')"]),
    ("two manifests whose sample times differ", lambda d: _yaml_copy(d, given={**_given(d), "sample_time": "1.44 ms"}),
     ["manifest.json and manifest.yaml", "say different things (first in 'given')"]),
    ("a broken YAML beside the JSON", lambda d: (d / "manifest.yml").write_text("runs: [\n"),
     ["manifest.yml", "not valid YAML"]),
    # an adversarial pass's tracebacks, hangs and misreadings (stop 32)
    ("manifests that differ by a null field", lambda d: (_yaml_copy(d), _edit_manifest(d, foo=None)),
     ["say different things (first in 'foo')"]),
    ("nesting 1000 deep", lambda d: (d / "manifest.json").write_text('{"x": ' + "[" * 1000 + "]" * 1000 + "}"),
     ["manifest.json: JSON nested too deeply"]),
    ("a 5000-digit number", lambda d: (d / "manifest.json").write_text(
        (d / "manifest.json").read_text().replace('"0.001 s"', "9" * 5000, 1)),
     ["manifest.json", "a number is too long"]),
    ("YAML aliases ten levels of ten", lambda d: _alias_bomb(d),
     ["manifest.yaml", "YAML aliases (*name) are not allowed here"]),
    ("YAML nested 100000 deep", lambda d: ((d / "manifest.yaml").write_text("x: " + "[" * 100_000 + "\n"),
                                          (d / "manifest.json").unlink()),
     ["manifest.yaml: YAML nested too deeply"]),
    ("a YAML manifest of 60000 values", lambda d: ((d / "manifest.yaml").write_text("x: [" + "1, " * 60_000 + "1]\n"),
                                                  (d / "manifest.json").unlink()),
     ["manifest.yaml: YAML document too large"]),
    ("an unpaired surrogate in station", lambda d: (d / "manifest.json").write_text(
        (d / "manifest.json").read_text().replace('"station": "', '"station": "\\ud800', 1)),
     ["field station", "unpaired surrogate"]),
    ("Kp of 1e308", lambda d: _edit_manifest(d, runs=[{**r, "controller": {"Kp": 1e308}} for r in _runs(d)]),
     ["runs.0.controller.Kp", "at most"]),
    ("a bore of 1e300 in", lambda d: _edit_manifest(d, given={**_given(d), "bore": "1e300 in"}),
     ["bore = '1e300 in' is outside the range a rig can have"]),
    ("Kamp of 1e200 mA/V", lambda d: _edit_manifest(d, given={**_given(d), "Kamp": "1e200 mA/V"}),
     ["Kamp = '1e200 mA/V' is outside the range"]),
    ("101 runs", lambda d: _edit_manifest(d, runs=[{**_runs(d)[0], "name": f"r{k}"} for k in range(101)]),
     ["field runs", "at most 100"]),
    ("a cell that overflows in inches", lambda d: _set_cell(_replace_header(d, "calibration.csv", "position [km],voltage [V]")
                                                            or d, "calibration.csv", 3, 0, "1e308"),
     ["calibration.csv: row 3, column 'position': '1e308' is not a finite number once converted to in"]),
    ("a number with an underscore", lambda d: _set_cell(d, "calibration.csv", 3, 0, "1_0"),
     ["calibration.csv: row 3, column 'position': '1_0' is not a number"]),
    ("a run file that is a folder", lambda d: ((d / "ramp_pi.csv").unlink(), (d / "ramp_pi.csv").mkdir()),
     ["ramp_pi.csv: is a folder, not a CSV file"]),
    # read as what they are, not as 1, 90 or "a number" (stop 33)
    ("Kp: true", lambda d: _edit_manifest(d, runs=[{**r, "controller": {"Kp": True}} for r in _runs(d)]),
     ["field runs.0.controller.Kp should be a number, not true/false"]),
    ("a 400-digit Kp", lambda d: (d / "manifest.json").write_text(json.dumps(
        {**json.loads((d / "manifest.json").read_text()),
         "runs": [{**r, "controller": {"Kp": 10**400}} for r in _runs(d)]})),
     ["field runs.0.controller.Kp should be a number, not a number beyond a double's range"]),
    ("a YAML Kp of 1:30", lambda d: ((d / "manifest.yaml").write_text(
        yaml.safe_dump({**json.loads((d / "manifest.json").read_text()), "runs": [{**_runs(d)[0], "controller": {"Kp": "@"}}]})
        .replace("Kp: '@'", "Kp: 1:30")), (d / "manifest.json").unlink()),
     ["manifest.yaml: field runs.0.controller.Kp should be a number, not text"]),
]


def _runs(ds: Path) -> list[dict]:
    return json.loads((ds / "manifest.json").read_text())["runs"]


def _set_cell(ds: Path, file: str, line: int, col: int, text: str) -> None:
    """Cell ``col`` of line ``line`` (1-based) of ``file`` set to ``text``."""
    lines = (ds / file).read_text().splitlines()
    cells = lines[line - 1].split(",")
    cells[col] = text
    lines[line - 1] = ",".join(cells)
    (ds / file).write_text("\n".join(lines) + "\n")


def _alias_bomb(ds: Path) -> None:
    """A manifest.yaml of 10 levels of 10 aliases (10¹⁰ values once expanded), and the JSON one removed."""
    text = "x0: &a0 [" + ", ".join(["lol"] * 10) + "]\n"
    text += "".join(f"x{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 10) + "]\n" for i in range(1, 10))
    (ds / "manifest.yaml").write_text(text)
    (ds / "manifest.json").unlink()


@pytest.mark.parametrize(("name", "breaker", "words"), BAD_CASES, ids=[c[0] for c in BAD_CASES])
def test_bad_dataset_gives_specific_error(ds: Path, name: str, breaker, words: list[str]) -> None:  # noqa: ANN001
    breaker(ds)
    with pytest.raises(DatasetError) as exc:
        load(ds)
    message = str(exc.value)
    assert "\n" not in message
    for w in words:
        assert w in message, f"{name}: {message!r} lacks {w!r}"


@pytest.mark.parametrize(
    ("row", "value", "words"),
    [(5, "nan", ["row 5", "'y'", "finite"]), (7, "abc", ["row 7", "not a number"])],
)
def test_bad_cell_names_row_and_column(ds: Path, row: int, value: str, words: list[str]) -> None:
    lines = (ds / "step_kp25.csv").read_text().splitlines()
    cells = lines[row - 1].split(",")
    cells[2] = value
    lines[row - 1] = ",".join(cells)
    (ds / "step_kp25.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(DatasetError) as exc:
        load(ds)
    assert all(w in str(exc.value) for w in ["step_kp25.csv", *words])


def test_non_monotonic_time_and_too_few_points(ds: Path) -> None:
    lines = (ds / "ramp_p.csv").read_text().splitlines()
    lines[10], lines[11] = lines[11], lines[10]
    (ds / "ramp_p.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(DatasetError, match=r"ramp_p.csv: time is not strictly increasing at row 12"):
        load(ds)
    (ds / "ramp_p.csv").write_text("\n".join(lines[:5]) + "\n")
    with pytest.raises(DatasetError, match=r"ramp_p.csv: 4 data rows, need at least 20"):
        load(ds)


def test_a_missing_sample_or_a_wrong_sample_time_is_refused_by_every_verb(ds: Path,
                                                                          capsys: pytest.CaptureFixture[str]) -> None:
    """One row per controller sample (docs/reference/dataset-format.md): checked on load, so that ``grader key``
    never writes a key from a sample time the data do not have (the predictions depend on it)."""
    lines = (ds / "ramp_p.csv").read_text().splitlines()
    (ds / "ramp_p.csv").write_text("\n".join(lines[:30] + lines[40:]) + "\n")  # data rows 29-38 lost
    with pytest.raises(DatasetError, match=r"run ramp_p \(ramp_p.csv\): .* \(row 31 is .* ms after the one before\)"):
        load(ds)
    (ds / "ramp_p.csv").write_text("\n".join(lines) + "\n")
    given = json.loads((ds / "manifest.json").read_text())["given"]
    _edit_manifest(ds, given={**given, "sample_time": "0.002 s"})  # the data are sampled every millisecond
    assert main(["key", str(ds), "-o", str(ds.parent / "key.json")]) == 2
    err = capsys.readouterr().err
    assert "not evenly at the manifest's sample_time of 2 ms" in err and err.count("\n") == 1
    assert not (ds.parent / "key.json").exists()


def test_a_late_stamp_loads_though_the_diagnosis_cannot_place_it(ds: Path) -> None:
    """A logger's jitter (one row 0.3 of a sample late, stamps printed to the microsecond) is no missing sample: the
    load (and so a key) takes it; the diagnosis, which puts every row on its sample, names it."""
    from grader.datasets.sampling import sample_times

    lines = (ds / "ramp_p.csv").read_text().splitlines()
    for k in range(1, len(lines)):
        cells = lines[k].split(",")
        cells[0] = f"{float(cells[0]) + 0.000123 + (0.0003 if k == 100 else 0.0):.6f}"  # stamps off the ms
        lines[k] = ",".join(cells)
    (ds / "ramp_p.csv").write_text("\n".join(lines) + "\n")
    run = next(r for r in load(ds).runs if r.name == "ramp_p")
    with pytest.raises(DatasetError, match=r"\(row 101 is 1\.3 ms after the one before\)"):
        sample_times(run, 0.001)


def test_a_reading_too_large_for_any_rig_is_named(ds: Path) -> None:
    """Beyond 1e12 in internal units, sums of squares over a run could overflow (the diagnosis failed on 1e300)."""
    lines = (ds / "step_kp10.csv").read_text().splitlines()
    cells = lines[9].split(",")
    cells[2] = "1e300"
    lines[9] = ",".join(cells)
    (ds / "step_kp10.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(DatasetError, match=r"step_kp10.csv: row 10, column 'y': '1e300' is too large for a reading"):
        load(ds)


def test_blank_lines_inside_a_file_do_not_shift_the_rows_an_error_names(ds: Path) -> None:
    """Rows are the file's lines: two blank lines before data line 5 put a bad cell on data line 7 at line 9."""
    path = ds / "step_kp25.csv"
    text = path.read_text()
    lines = text.splitlines()
    cells = lines[6].split(",")
    cells[2] = "abc"
    lines[6] = ",".join(cells)
    path.write_text("\n".join([*lines[:4], "", " , ", *lines[4:]]) + "\n")
    with pytest.raises(DatasetError, match=r"step_kp25.csv: row 9, column 'y': 'abc' is not a number"):
        load(ds)
    path.write_text(text)
    lines = (ds / "ramp_p.csv").read_text().splitlines()
    lines[10], lines[11] = lines[11], lines[10]
    (ds / "ramp_p.csv").write_text("\n".join([*lines[:3], "", *lines[3:]]) + "\n")
    with pytest.raises(DatasetError, match=r"ramp_p.csv: time is not strictly increasing at row 13"):
        load(ds)


@pytest.mark.parametrize(("cell", "said"), [
    ('"' + "x" * 200_000 + '"', "step_kp25.csv: row 7 is not readable as CSV (field larger than field limit"),
    ('"0.1', 'step_kp25.csv: row 7 is not readable as CSV (unexpected end of data); a quote (") opens there'),
    ('"0.1"5', "step_kp25.csv: row 7 is not readable as CSV (',' expected after '\"')"),
    ('"0.1\n0.2"', "step_kp25.csv: row 7, column 'y': '0.1\\n0.2' is not a number"),
], ids=["a cell over 128 kB", "an unclosed quote", "text after a quote", "a quoted cell over two lines"])
def test_a_record_the_csv_module_refuses_or_spans_lines_is_named_where_it_starts(ds: Path, cell: str,
                                                                                 said: str) -> None:
    """A record is named by the line it starts on; one the csv module cannot read was a traceback."""
    path = ds / "step_kp25.csv"
    lines = path.read_text().splitlines()
    cells = lines[6].split(",")
    cells[2] = cell
    lines[6] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(DatasetError) as exc:
        load(ds)
    assert str(exc.value).startswith(said)


def test_cli_key_errors_are_one_line_without_traceback(ds: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _replace_header(ds, "flow.csv", "input [V],flow [lbf]")
    assert main(["key", str(ds), "-o", str(ds / "key.json")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err and "flow.csv" in err


@settings(max_examples=60, deadline=None)
@given(st.text(max_size=40))
def test_arbitrary_header_never_crashes(tmp_path_factory: pytest.TempPathFactory, header: str) -> None:
    from grader.datasets.csvio import read_table
    from grader.datasets.schema import CALIBRATION

    path = tmp_path_factory.mktemp("h") / "c.csv"
    path.write_text(header.replace("\n", " ") + "\n0,1\n1,2\n2,3\n", encoding="utf-8")
    try:
        read_table(path, CALIBRATION)
    except DatasetError as exc:
        assert "c.csv" in str(exc)


CELL = st.one_of(
    st.floats(allow_nan=False, allow_infinity=False, width=64).map(repr),
    st.floats(-1e6, 1e6).map(lambda v: f" {v:.4g}\t"),
    st.integers(-10**6, 10**6).map(str),
    st.sampled_from(["1e400", "nan", "-inf", "1_0", "abc", "", "١٢", "0x10", " "]),
)


@settings(max_examples=150, deadline=None)
@given(st.lists(st.tuples(CELL, CELL, CELL), min_size=1, max_size=30), st.booleans())
def test_whole_columns_read_as_cell_by_cell_does(rows: list[tuple[str, str, str]], ragged: bool) -> None:
    """The column-at-once read (numpy) gives the arrays, or the error naming the first faulty cell, of the
    cell-by-cell read; in mm, so a cell can also overflow once converted."""
    from grader.datasets.csvio import _convert, _convert_cells

    header = [("position", 1 / 25.4, "in"), ("note", float("nan"), ""), ("voltage", 1.0, "V")]
    body = [(k + 2, list(r) if not (ragged and k == len(rows) // 2) else list(r[:2])) for k, r in enumerate(rows)]
    path = Path("c.csv")

    def outcome(read):  # noqa: ANN001, ANN202
        try:
            return {k: v.tobytes() for k, v in read(path, header, body).items()}
        except DatasetError as exc:
            return str(exc)

    assert outcome(_convert) == outcome(_convert_cells)


def test_symlinked_files_are_refused_and_never_echoed(ds: Path) -> None:
    secret = ds.parent / "secret.txt"
    secret.write_text("root:x:0:0:root:/root:/bin/bash\n")
    (ds / "calibration.csv").unlink()
    (ds / "calibration.csv").symlink_to(secret)
    with pytest.raises(DatasetError) as exc:
        load(ds)
    assert "symbolic link" in str(exc.value) and "root:x" not in str(exc.value)


def test_long_bad_cells_are_clipped_in_messages(ds: Path) -> None:
    _replace_header(ds, "friction.csv", "x" * 500 + ",force [lbf]")
    with pytest.raises(DatasetError) as exc:
        load(ds)
    assert len(str(exc.value)) < 200


@pytest.mark.parametrize("changes", [{}, {"given": {"weight": "0.0290 klbf", "bore": "12.7 mm", "rod": "0.25 in",
                                                   "supply_pressure": "1000 psi", "Kamp": "0.005 A/V",
                                                   "i_max": "0.05 A", "sample_time": "1 ms"}}],
                         ids=["as written", "in other units"])
def test_a_yaml_manifest_that_says_what_the_json_one_says_is_no_conflict(ds: Path, changes: dict) -> None:
    before = load(ds)
    _yaml_copy(ds, **changes)
    after = load(ds)
    assert after.manifest == before.manifest and after.inputs_sha256 == before.inputs_sha256
