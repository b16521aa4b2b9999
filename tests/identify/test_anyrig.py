"""A sample of benchmarks/anyrig_benchmark.py: rigs of the realistic space (both feedback
conventions; one lightly damped with no 25 % gain, one heavily damped with a large B; one whose
instability run saturates the valve, one whose oscillation friction stops), keyed, graded with a
fully correct submission and checked in process, with the benchmark's recovery bounds."""

from __future__ import annotations

import importlib.util
import sys
from dataclasses import replace
from types import ModuleType

import pytest

from grader.model.params import Controller
from grader.stations import Station, repo_root
from grader.synth import RunPlan


def _benchmark() -> ModuleType:
    path = repo_root() / "benchmarks" / "anyrig_benchmark.py"
    spec = importlib.util.spec_from_file_location("anyrig_benchmark", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


BENCH = _benchmark()


@pytest.mark.parametrize(("seed", "k", "feedback", "not_reachable"), [
    (1, 1, "volts", True), (1, 15, "inches", False),
    (0, 104, "volts", True),  # run at 1.7× critical: grows slowly while friction holds it back, then the valve saturates
    (0, 53, "volts", False),  # run just past critical: the oscillation grows, then friction stops it
])
def test_rig_is_keyed_graded_and_recovered(seed: int, k: int, feedback: str, not_reachable: bool) -> None:
    out = BENCH.one_rig(k, seed, False)
    assert out.feedback == feedback and not out.failure, out.failure
    assert out.exits == {"key": 0, "grade": 0, "check": 0}
    assert out.not_correct == []
    assert ("Kp_25_overshoot" in out.not_reachable) == not_reachable
    for name, bound in BENCH.BOUNDS.items():
        assert out.errors[name] <= bound, f"{name} off by {100 * out.errors[name]:.2f} %"


def test_a_rig_whose_oscillation_cannot_be_read_is_keyed_graded_and_diagnosed(monkeypatch: pytest.MonkeyPatch) -> None:
    """Seed 7, rig 5 (inches) with its instability run recorded at Kp = 79 V/V, where friction stops
    the oscillation after 7 cycles (a student who did not raise the gain further): the key says β/Vt
    and Kce are not identifiable, and every verb, diagnose included, still exits 0."""
    lab_runs = BENCH.lab_runs

    def marginal(st: Station) -> list[RunPlan]:
        scale = 1.0 if st.params().feedback == "volts" else st.params().Kpot
        return [replace(r, controller=Controller(79.0 * scale)) if r.kind == "instability" else r for r in lab_runs(st)]

    monkeypatch.setattr(BENCH, "lab_runs", marginal)
    out = BENCH.one_rig(5, 7, True)
    assert out.feedback == "inches" and not out.failure, out.failure
    assert out.not_identifiable
    assert out.exits == {"key": 0, "grade": 0, "check": 0, "diagnose": 0}
    assert out.not_correct == []
    assert out.errors["Kpot"] <= BENCH.BOUNDS["Kpot"] and out.errors["Kq"] <= BENCH.BOUNDS["Kq"]
