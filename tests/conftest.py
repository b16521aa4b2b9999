"""Shared fixtures: the default station and a synthetic dataset generated from it."""

from __future__ import annotations

from pathlib import Path

import pytest

from grader.stations import Station, load_station
from grader.synth import make_dataset


@pytest.fixture(scope="session")
def station() -> Station:
    return load_station("default")


@pytest.fixture(scope="session")
def linear_dataset(tmp_path_factory: pytest.TempPathFactory, station: Station) -> Path:
    """A dataset of the default station simulated with the linear model and noise (seed 11)."""
    return make_dataset(station, tmp_path_factory.mktemp("linear") / "ds", seed=11)
