"""Shared fixtures for the grading tests: the default station's key, the rubric, graded fixtures."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from grader.grading.context import KeyContext, KeyStore
from grader.grading.grade import GradeOptions
from grader.grading.pipeline import grade_batch, read_all
from grader.grading.results import SubmissionResult
from grader.grading.rubric import Rubric, load_rubric

ROOT = Path(__file__).resolve().parents[2]
FIXTURES = ROOT / "submissions_fixtures" / "grading"
EXPECTED = json.loads((ROOT / "submissions_fixtures" / "grading_expected.json").read_text())
FIXTURE_DATASETS = ROOT / "reference_solutions" / "datasets"  # the station dataset the fixtures were made from
FIXTURE_KEYS = ROOT / "reference_solutions" / "keys"  # and its checked-in key


@pytest.fixture(scope="session")
def store(pytestconfig: pytest.Config, tmp_path_factory: pytest.TempPathFactory) -> KeyStore:
    """The fixtures' station dataset and key; keys built from other datasets are kept in pytest's
    cache between runs (in a temporary folder when the cache is disabled)."""
    cache = getattr(pytestconfig, "cache", None)
    folder = Path(cache.mkdir("grader-keys")) if cache is not None else tmp_path_factory.mktemp("grader-keys")
    return KeyStore(datasets_dir=FIXTURE_DATASETS, keys_dir=FIXTURE_KEYS, cache_dir=folder)


def key_args(store: KeyStore) -> list[str]:
    """CLI options that make a verb use the test's keys."""
    return ["--datasets", str(store.datasets_dir), "--keys", str(store.keys_dir), "--key-cache", str(store.cache_dir)]


@pytest.fixture(scope="session")
def kc(store: KeyStore) -> KeyContext:
    return store.for_station("default")


@pytest.fixture(scope="session")
def rubric() -> Rubric:
    return load_rubric(ROOT / "rubrics" / "hydraulic_positioner.yaml")


@pytest.fixture(scope="session")
def opts(rubric: Rubric) -> GradeOptions:
    return GradeOptions(rubric=rubric, convention="volts")


@pytest.fixture(scope="session")
def graded(opts: GradeOptions, store: KeyStore, kc: KeyContext) -> dict[str, SubmissionResult]:
    """Every fixture graded once: file name -> result."""
    paths = sorted(FIXTURES.iterdir())
    results = list(grade_batch(read_all(paths, opts), opts, store, workers=1))
    return {Path(r.source).name: r for r in results}
