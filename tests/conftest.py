"""Shared fixtures: the default station, a synthetic dataset generated from it, key-leak detection."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from grader.grading.context import KeyContext
from grader.stations import Station, load_station
from grader.synth import make_dataset


@pytest.fixture(scope="session")
def station() -> Station:
    return load_station("default")


@pytest.fixture(scope="session")
def linear_dataset(tmp_path_factory: pytest.TempPathFactory, station: Station) -> Path:
    """A dataset of the default station simulated with the linear model and noise (seed 11)."""
    return make_dataset(station, tmp_path_factory.mktemp("linear") / "ds", seed=11)


def _key_numbers(kc: KeyContext) -> set[str]:
    """Every way a key value could be printed: 3 to 6 significant figures, per scalar and per pole."""
    values: list[float] = []
    for name, entry in kc.key.quantities.items():
        if isinstance(entry.value, (int, float)):
            values.append(float(entry.value))
        elif name == "closed_loop_poles":
            values += [abs(x) for run in entry.value for pole in run["poles"] for x in pole]
    values += list(kc.key.model.model_dump().values())
    out = set()
    for v in values:
        if v == 0 or float(v).is_integer():
            continue
        for digits in range(3, 7):
            out.add(f"{abs(v):.{digits}g}")
    return {t for t in out if len(t.replace(".", "").replace("0", "")) >= 3}


@pytest.fixture(scope="session")
def key_numbers() -> Callable[[KeyContext], set[str]]:
    """Every way a key's values could be printed (3 to 6 significant figures): for leak checks."""
    return _key_numbers
