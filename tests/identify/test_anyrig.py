"""A sample of benchmarks/anyrig_benchmark.py: two rigs of the realistic space (one per feedback
convention; one lightly damped with no 25 % gain, one heavily damped with a large B), keyed,
graded with a fully correct submission and checked in process, with the benchmark's recovery bounds."""

from __future__ import annotations

import importlib.util
import sys
from types import ModuleType

import pytest

from grader.stations import repo_root


def _benchmark() -> ModuleType:
    path = repo_root() / "benchmarks" / "anyrig_benchmark.py"
    spec = importlib.util.spec_from_file_location("anyrig_benchmark", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


BENCH = _benchmark()


@pytest.mark.parametrize(("k", "feedback", "not_reachable"), [(1, "volts", True), (15, "inches", False)])
def test_rig_is_keyed_graded_and_recovered(k: int, feedback: str, not_reachable: bool) -> None:
    out = BENCH.one_rig(k, 1, False)
    assert out.feedback == feedback and not out.failure, out.failure
    assert out.exits == {"key": 0, "grade": 0, "check": 0}
    assert out.not_correct == []
    assert ("Kp_25_overshoot" in out.not_reachable) == not_reachable
    for name, bound in BENCH.BOUNDS.items():
        assert out.errors[name] <= bound, f"{name} off by {100 * out.errors[name]:.2f} %"
