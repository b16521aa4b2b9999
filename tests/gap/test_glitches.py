"""One-sample glitches of a position reading: found where a reading jumps out and back beyond anything the run's
motion does in one sample, never on a ringing step, a motion's corner or a quantised reading's flicker."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from grader.gap.glitches import MOST, find_glitches

T = 0.0018
t = np.arange(1500) * T
NOISE = 1.4e-4 * np.random.default_rng(7).standard_normal(t.size)


def _ring(samples_per_period: float, amplitude: float = 0.05) -> np.ndarray:
    return amplitude * np.exp(-t / 0.5) * np.sin(2 * np.pi * t / (samples_per_period * T)) + NOISE


def _spiked(y: np.ndarray, at: dict[int, float]) -> np.ndarray:
    y = y.copy()
    for k, size in at.items():
        y[k] += size
    return y


STEP = np.where(t > 0.1, 0.1 * (1 - np.exp(-(t - 0.1) / 0.02)), 0.0) + NOISE
CASES = [
    ("ringing, 8 samples a period", _ring(8), []),
    ("ringing, 4 samples a period", _ring(4), []),
    ("step's corner", np.where(t > 0.1, 5 * (t - 0.1), 0.0), []),
    ("quantised reading flickering by a count", np.round(_ring(30) / 0.018) * 0.018, []),
    ("a count's flicker on a flat reading", _spiked(np.zeros(200), {20: 0.018, 50: 0.018, 120: -0.018, 150: 0.018}),
     []),
    ("a 5 in spike on a step", _spiked(STEP, {500: 5.0}), [500]),
    ("a spike below the step's slew", _spiked(STEP, {300: 0.02}), []),
    ("two spikes of one size", _spiked(_ring(30), {1: 0.1, 1498: -0.1}), [1, 1498]),
    ("a spike on a noiseless flat reading", _spiked(np.zeros(50), {20: 1.0}), [20]),
    (f"{MOST} spikes", _spiked(STEP, {100: 1.0, 700: -2.0, 1200: 0.5}), [100, 700, 1200]),
    (f"{MOST + 1} spikes (a property of the sensor)", _spiked(STEP, {100: 1.0, 700: -2.0, 1200: 0.5, 1300: 1.0}), []),
]


@pytest.mark.parametrize(("name", "y", "found"), CASES, ids=[c[0] for c in CASES])
def test_glitches_found(name: str, y: np.ndarray, found: list[int]) -> None:
    assert find_glitches(y) == found


@settings(max_examples=60, deadline=None)
@given(periods=st.lists(st.floats(4.0, 400.0), min_size=1, max_size=3),
       amplitudes=st.lists(st.floats(1e-3, 1.0), min_size=3, max_size=3),
       at=st.integers(1, t.size - 2), times=st.floats(4.5, 100.0), sign=st.sampled_from([-1.0, 1.0]))
def test_a_smooth_reading_has_none_and_a_spike_beyond_its_motion_is_found(
        periods: list[float], amplitudes: list[float], at: int, times: float, sign: float) -> None:
    """Sums of sinusoids sampled 4 to 400 times a period, with noise: no glitch; one reading moved out by more than
    4 times the largest step of the reading (its jump to a neighbour is then more than 3 times any other step)
    plus twice the noise's largest: exactly it."""
    y = NOISE + sum(a * np.sin(2 * np.pi * t / (p * T)) for p, a in zip(periods, amplitudes))
    assert find_glitches(y) == []
    size = times * float(np.max(np.abs(np.diff(y)))) + 2 * float(np.max(np.abs(NOISE)))
    assert find_glitches(_spiked(y, {at: sign * size})) == [at]
