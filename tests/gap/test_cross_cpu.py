"""Cross-CPU determinism of the diagnosis where the loop is fitted from the runs (no friction test).

``OPENBLAS_CORETYPE`` forces the BLAS kernels of an older or newer CPU (see tests/core/test_cross_cpu.py).
Before the loop fit, the smoothing weights and the fitter's step arithmetic were made independent of BLAS, such a
dataset gave a β/Vt differing in the 5th digit, and candidates' shrinks in the 6th, from one kernel to another.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from .conftest import MakeDataset

CORE_TYPES = ("Prescott", "Nehalem", "Haswell")


def _without_friction_test(src: Path, dst: Path) -> Path:
    shutil.copytree(src, dst)
    manifest = json.loads((dst / "manifest.json").read_text(encoding="utf-8"))
    (dst / manifest.pop("friction")).unlink()
    (dst / "manifest.json").write_text(json.dumps(manifest, indent=2) + "\n", encoding="utf-8")
    return dst


def _diagnosis(core: str, dataset: Path, out: Path) -> dict[str, bytes]:
    env = {**os.environ, "OPENBLAS_CORETYPE": core}
    subprocess.run([sys.executable, "-m", "grader.cli", "diagnose", str(dataset), "-o", str(out)],
                   env=env, check=True, capture_output=True, timeout=300)
    return {p.name: p.read_bytes() for p in sorted(out.iterdir())}


@pytest.mark.parametrize(("friction_test", "source"), [(False, "runs"), (True, "identified")])
def test_a_diagnosis_is_the_same_bytes_under_every_blas_core_type(make: MakeDataset, tmp_path: Path,
                                                                  friction_test: bool, source: str) -> None:
    """Without a friction test the loop is fitted from the runs; with one, the students' identification
    (the default station: volts feedback, a calibration file) gives it."""
    made = make("xcpu_pq", {"pressure_flow_nonlinearity": {}, "valve_hysteresis": {"width": 0.6}})
    dataset = made if friction_test else _without_friction_test(made, tmp_path / "xcpu_pq")
    written = {core: _diagnosis(core, dataset, tmp_path / core) for core in CORE_TYPES}
    first = written[CORE_TYPES[0]]
    assert json.loads(first["diagnosis.json"])["baseline"]["source"] == source
    for core, files in written.items():
        assert files.keys() == first.keys()
        for name, data in files.items():
            assert data == first[name], f"OPENBLAS_CORETYPE={core} wrote a different {name}"
