"""Cross-CPU determinism of the diagnosis where the loop is fitted from the runs (no friction test), and of the
benchmark's generator.

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

import numpy as np
import pytest

from grader.model.rig_ivp import FixedOrderRK45

from ..core.test_cross_cpu import _core_types
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


#: Run A's dataset 163 (seed 300): a random station of the benchmark, the orifice law withheld (made by the
#: current generator, whose instability gain the solve_ivp rig decides).
GENERATE = """
import sys
from pathlib import Path
from grader.gap.bench import make_case_dataset
from grader.model.effects import EffectSet
from grader.stations import Station
station = Station.model_validate({
    "station": "default", "feedback": "inches",
    "given": {"weight": "57.1 lbf", "bore": "0.5 in", "rod": "0.25 in", "supply_pressure": "1000 psi",
              "Kamp": "5 mA/V", "i_max": "50 mA", "sample_time": "0.00201 s"},
    "truth": {"Kq": "0.04705 in^3/s/mA", "Kpot": "0.8242 V/in", "pot_offset": "4.2 V",
              "beta_over_Vt": "76267.5 psi/in^3", "Kce": "6.075e-04 in^3/s/psi", "B": "0 lbf*s/in",
              "leakage": "0.11 in^3/s", "null_offset": "0.4 mA", "flow_saturation": "42 mA"},
    "noise": {"position": "1.583e-04 in", "voltage": "0.002 V", "flow": "0.006 in^3/s", "force": "0.08 lbf"}})
effects = EffectSet({"pressure_flow_nonlinearity": {}})
make_case_dataset(station, effects, Path(sys.argv[1]) / "ds", seed=166724841, friction_test=False)
"""


def test_a_benchmark_dataset_is_the_same_bytes_under_every_blas_core_type(tmp_path: Path) -> None:
    """The benchmark's generator (scipy's solve_ivp, :mod:`grader.model.rig_ivp`) writes the same files whatever
    BLAS kernels run. With scipy's float64 RK45, whose stage sums go through BLAS, run A's dataset 163 had a
    different instability run under Prescott's kernels than under Haswell's, and a pinned test passed on one CPU
    and failed on another."""
    written = {}
    for core in _core_types():  # SkylakeX's kernels too where the CPU has AVX-512: the old generator differed there
        subprocess.run([sys.executable, "-c", GENERATE, str(tmp_path / core)], check=True, capture_output=True,
                       env={**os.environ, "OPENBLAS_CORETYPE": core}, timeout=300)
        written[core] = {p.name: p.read_bytes() for p in sorted((tmp_path / core / "ds").iterdir())}
    first = written["Prescott"]
    assert {"instability.csv", "manifest.json"} <= first.keys()
    for core, files in written.items():
        assert files == first, f"OPENBLAS_CORETYPE={core} generated different files"


def test_the_generators_rk45_sums_its_stages_in_long_double() -> None:
    """What keeps BLAS out of the generator's integration (scipy's internals: the stage array ``K``, allocated once
    and written in place): after a step, the stages and the state are long double."""
    solver = FixedOrderRK45(lambda t, y: -y, 0.0, np.array([1.0, 2.0]), 1.0, first_step=0.1)
    solver.step()
    assert solver.K.dtype == np.longdouble and solver.y.dtype == np.longdouble
    assert solver.dense_output()(0.05).dtype == np.longdouble
