"""Mains pickup found in the runs' readings at rest (grader.gap.hum)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from grader.gap import hum
from grader.gap.runs import GapRun
from grader.model.params import Controller

SIGMA = 4e-4  # [in], the default station's reading noise


def _runs(seed: int, pickup: float, f: float = 60.0, rest: float = 0.1, sample: float = 0.001) -> list[GapRun]:
    """Six runs whose readings are white noise and ``pickup`` [in] of hum at ``f`` [Hz] (random phase), each resting
    ``rest`` [s] before its command; after the command, a large motion that the test must not look at."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(6):
        t = sample * np.arange(int(1.5 / sample))
        y = rng.normal(0.0, SIGMA, t.size) + pickup * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
        y = y + np.where(t >= rest, 0.1 * np.sin(2 * np.pi * 60.0 * t), 0.0)  # after the command: no rest
        z = np.zeros_like(t)
        out.append(GapRun(f"r{k}", "step", Controller(1.0), t, z, y, z, rest, 1.0, z))
    return out


@pytest.mark.parametrize(("f", "sample", "rest"), [(60.0, 0.001, 0.1), (50.0, 0.0005, 0.1), (60.0, 0.005, 0.1),
                                                    (60.0, 0.01, 0.3)])
def test_pickup_as_large_as_the_reading_noise_is_found_at_its_frequency(f: float, sample: float, rest: float) -> None:
    """The independent simulator's pickup: 0.5 to 1.5 times the reading noise, at 60 Hz. With 10 ms samples it
    aliases to 40 Hz, where it is still found as 60 Hz, given 30 readings at rest (10 are too few: the independent
    simulator's rigs sampled every 2.5 ms or slower went unfound)."""
    found = hum.lines(_runs(3, SIGMA, f, rest=rest, sample=sample))
    assert found == (f,)


@pytest.mark.parametrize("seed", range(40))
def test_readings_without_pickup_show_no_line_and_motion_after_the_command_is_not_looked_at(seed: int) -> None:
    """Noise alone at rest (and a large 60 Hz motion after each command): no line, on every one of 40 rigs."""
    assert hum.lines(_runs(seed, 0.0)) == ()


def test_the_instability_runs_ringing_at_rest_is_no_pickup() -> None:
    """A rig resting at its critical gain already rings: a 60 Hz line in the instability run's rest alone is the loop's
    own, not the mains (run A's 0001, which has no pickup, showed one at p = 3e-13)."""
    runs = _runs(2, 0.0)
    ringing = runs[0].y + np.where(runs[0].t < runs[0].start, 3 * SIGMA * np.sin(2 * np.pi * 60.0 * runs[0].t), 0.0)
    runs[0] = replace(runs[0], kind="instability", y=ringing)
    assert hum.lines(runs) == ()
    assert hum.lines([replace(runs[0], kind="step"), *runs[1:]]) == (60.0,)


def test_runs_with_too_few_readings_at_rest_decide_nothing() -> None:
    assert hum.lines(_runs(1, 10 * SIGMA, rest=0.005)) == ()


def test_the_basis_is_orthonormal_and_drops_what_aliases_away() -> None:
    t = 0.005 * np.arange(300)  # 200 Hz sampling: 100 Hz is the Nyquist line (its sine vanishes), 150 Hz aliases to 50
    q = hum.basis(t, hum.MAINS)
    assert np.allclose(q.T @ q, np.eye(q.shape[1]), atol=1e-12)
    assert q.shape[1] == 2 + 2 + 2 + 1 + 2 + 0 + 2  # 1, t; 50; 60; 100 (cos only); 120; 150 (= 50); 180
