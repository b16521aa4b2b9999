"""Answer keys: complete, deterministic, provenance recorded, checked-in default up to date."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from grader.cli import main
from grader.datasets import load
from grader.errors import KeyFileError
from grader.keys import build_key, key_json, read_key, write_key
from grader.stations import reference_dir

CANONICAL = ["Kpot", "Kq", "leakage", "B", "Fc", "omega_crit", "Kp_crit", "beta_over_Vt", "Kce", "Kp_no_overshoot",
             "Kp_25_overshoot", "ramp_ess_P", "closed_loop_poles", "char_poly_a2", "char_poly_a1", "char_poly_a0_per_Kp"]


@pytest.fixture(scope="module")
def key_text(linear_dataset: Path) -> str:
    return key_json(build_key(load(linear_dataset)))


def test_key_has_every_canonical_item_with_unit_and_interval(key_text: str) -> None:
    from grader.units import parse_unit

    data = json.loads(key_text)
    for item in CANONICAL:
        entry = data["quantities"][item]
        assert set(entry) == {"value", "unit", "interval", "method", "inputs", "status", "reason", "note"}
        assert entry["status"] == "ok" and entry["reason"] is None
        parse_unit(entry["unit"]) if entry["unit"] != "dimensionless" else None
        if item != "closed_loop_poles":
            lo, hi = entry["interval"]
            assert lo <= entry["value"] <= hi
    assert data["generated_by"]["package"] == "grader" and data["inputs_sha256"]


def test_same_inputs_give_byte_identical_keys(linear_dataset: Path, key_text: str, tmp_path: Path) -> None:
    assert key_json(build_key(load(linear_dataset))) == key_text
    path = write_key(read_key(_write(tmp_path, key_text)), tmp_path / "again.json")
    assert path.read_text() == key_text


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "key.json"
    path.write_text(text)
    return path


def test_default_key_is_up_to_date() -> None:
    root = reference_dir()
    checked_in = (root / "keys" / "default.json").read_text()
    assert key_json(build_key(load(root / "datasets" / "default"))) == checked_in


def test_key_written_before_status_existed_still_loads(tmp_path: Path) -> None:
    data = json.loads((reference_dir() / "keys" / "default.json").read_text())
    for entry in data["quantities"].values():
        for field in ("status", "reason", "note"):
            entry.pop(field)
    key = read_key(_write(tmp_path, json.dumps(data)))
    assert all(e.status == "ok" and e.reachable for e in key.quantities.values())
    assert key.value("Kq") == data["quantities"]["Kq"]["value"]


def test_cli_key_writes_file_and_table(linear_dataset: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "k.json"
    assert main(["key", str(linear_dataset), "-o", str(out)]) == 0
    assert "beta_over_Vt" in capsys.readouterr().out
    assert read_key(out).quantities["Kq"].unit == "in**3/s/mA"


@pytest.mark.parametrize("text", ["{", "[]", '{"schema": "other"}', '{"schema": "grader.key/1", "station": 3}'])
def test_bad_key_files_raise(tmp_path: Path, text: str) -> None:
    with pytest.raises(KeyFileError):
        read_key(_write(tmp_path, text))


@pytest.mark.parametrize(
    ("change", "words"),
    [
        (lambda d: d["model"].update(foo=1.0), "model.foo"),
        (lambda d: d["model"].update(M=-1.0), "model.M"),
        (lambda d: d.update(feedback="mm"), "feedback"),
    ],
)
def test_key_model_block_is_validated(change, words: str, tmp_path: Path) -> None:  # noqa: ANN001
    data = json.loads((reference_dir() / "keys" / "default.json").read_text())
    change(data)
    with pytest.raises(KeyFileError, match=words):
        read_key(_write(tmp_path, json.dumps(data)))
