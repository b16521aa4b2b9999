"""Shared fixtures for the web tests: the service on the checked-in default station, and an app client."""

from __future__ import annotations

from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from grader.grading import tf
from grader.grading.context import KeyContext
from grader.web.app import WebOptions, create_app
from grader.web.service import CheckService, build_service

ROOT = Path(__file__).resolve().parents[2]
FIXTURES = ROOT / "submissions_fixtures" / "grading"
RUBRIC = ROOT / "rubrics" / "hydraulic_positioner.yaml"
REFERENCE = ROOT / "reference_solutions"


@pytest.fixture(scope="session")
def service() -> CheckService:
    svc = build_service(RUBRIC, REFERENCE / "datasets", REFERENCE / "keys")
    svc.warm()
    return svc


@pytest.fixture(scope="session")
def kc(service: CheckService) -> KeyContext:
    return service.store.for_station("default")


@pytest.fixture()
def client(service: CheckService) -> TestClient:
    """A fresh app (fresh rate-limit counters) with a limit the tests do not reach unless they mean to."""
    return TestClient(create_app(service, WebOptions(checks_per_minute=600, burst=200)), raise_server_exceptions=False)


def reference_texts() -> list[str]:
    """The reference expressions as the grader would print them (spaces removed): none may be sent."""
    return [str(e).replace(" ", "") for fb in ("volts", "inches") for e in tf._loop_forms(fb).values()]
