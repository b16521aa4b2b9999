"""One-sample glitches of a position reading: found where a reading jumps out and back beyond anything the run's
motion does in one sample, never on a ringing step, a motion's corner or a quantised reading's flicker."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from grader.gap.glitches import MOST, mend, search

T = 0.0018
t = np.arange(1500) * T
NOISE = 1.4e-4 * np.random.default_rng(7).standard_normal(t.size)


def find_glitches(y: np.ndarray) -> list[int]:
    """The glitches :func:`mend` mends: none where there are too many."""
    g = search(y)
    return [] if g.too_many else list(g.found)


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
    (f"{MOST + 1} spikes (a fault of the sensor)", _spiked(STEP, {100: 1.0, 700: -2.0, 1200: 0.5, 1300: 1.0}), []),
    (f"{MOST} large spikes and a smaller one", _spiked(STEP, {100: 5.0, 700: 5.0, 1200: 5.0, 1300: 1.0}), []),
    ("two spikes one sample apart (the reading between is clean)", _spiked(STEP, {300: 5.0, 302: 5.0}), [300, 302]),
    ("a two-sample glitch", _spiked(STEP, {300: 5.0, 301: -5.0}), []),
    ("the first reading", _spiked(STEP, {0: 5.0}), [0]),
    ("the last reading and one inside", _spiked(STEP, {t.size - 1: 5.0, 400: 5.0}), [400, t.size - 1]),
    ("a step followed within a sample, overshooting for one", np.array([0.0] * 20 + [1.5] + [1.0] * 100), []),
    ("a step ringing at 2.2 samples a period", np.where(np.arange(200) < 20, 0.0, 1.0 - np.exp(
        -0.25 * 2.86 * np.maximum(np.arange(200) - 20, 0)) * np.cos(2.86 * np.maximum(np.arange(200) - 20, 0))), []),
]


@pytest.mark.parametrize(("name", "y", "found"), CASES, ids=[c[0] for c in CASES])
def test_glitches_found(name: str, y: np.ndarray, found: list[int]) -> None:
    assert find_glitches(y) == found


@settings(max_examples=60, deadline=None)
@given(periods=st.lists(st.floats(4.0, 400.0), min_size=1, max_size=3),
       amplitudes=st.lists(st.floats(1e-3, 1.0), min_size=3, max_size=3),
       at=st.integers(1, t.size - 2), times=st.floats(7.5, 100.0), sign=st.sampled_from([-1.0, 1.0]))
def test_a_smooth_reading_has_none_and_a_spike_beyond_its_motion_is_found(
        periods: list[float], amplitudes: list[float], at: int, times: float, sign: float) -> None:
    """Sums of sinusoids sampled 4 to 400 times a period, with noise: no glitch; one reading moved out by more than
    7 times the largest step of the reading plus twice the noise's largest: exactly it (its jump to either
    neighbour is then more than 6 largest steps, 3 times any other step and 3 times how far its neighbours
    differ, at most 2 largest steps)."""
    y = NOISE + sum(a * np.sin(2 * np.pi * t / (p * T)) for p, a in zip(periods, amplitudes))
    assert find_glitches(y) == []
    size = times * float(np.max(np.abs(np.diff(y)))) + 2 * float(np.max(np.abs(NOISE)))
    assert find_glitches(_spiked(y, {at: sign * size})) == [at]


def test_glitches_one_sample_apart_are_mended_from_clean_neighbours_and_noted_by_row() -> None:
    """Mending both from the readings as recorded once turned the clean reading between them into a new glitch."""
    m = mend(_spiked(STEP, {300: 5.0, 302: 5.0}), t, "run a (a.csv)")
    np.testing.assert_allclose(m.y[299:304], STEP[299:304], atol=1e-3)
    assert m.rows == [302, 304]
    assert m.notes[0].startswith(f"run a (a.csv): the reading at row 302 (t = {t[300]:.6g} s) lies +5 in off its "
                               "neighbours and back within one sample")


def test_too_many_glitches_are_compared_as_recorded_with_one_note() -> None:
    recorded = _spiked(STEP, {100: 5.0, 700: 5.0, 1200: 5.0, 1300: 1.0})
    assert search(recorded).too_many
    m = mend(recorded, t, "run a (a.csv)")
    assert m.y is recorded and m.rows == [102, 702, 1202, 1302] and not m.flat
    assert m.notes == ["run a (a.csv): 4 readings jump out and back within one sample (rows 102, 702, 1202, 1302; up "
                     "to 5 in): more than 3 is a fault of the sensor or its wiring, not a logger's glitch; they are "
                     "compared as recorded"]


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10_000), at=st.sampled_from([0, 1, 299, 1200, t.size - 3]), size=st.floats(0.5, 5.0))
def test_two_glitches_a_sample_apart_are_found_whatever_the_noise(seed: int, at: int, size: float) -> None:
    """Which of the two glitches and the clean reading between them has the larger jump is the noise's draw; the
    clean one lies half as far from its four nearest readings' median, so it is never taken (it was, 1 time in 4)."""
    y = STEP - NOISE + 1.4e-4 * np.random.default_rng(seed).standard_normal(t.size)
    assert search(_spiked(y, {at: size, at + 2: size})).found == (at, at + 2)


@pytest.mark.parametrize("count", [MOST + 1, 8, 30])
def test_many_glitches_are_a_fault_of_the_sensor_however_many(count: int) -> None:
    """Each glitch's steps once counted as the motion every other had to exceed: 7 or more were found as none."""
    spiked = _spiked(STEP, {int(k): 5.0 for k in np.linspace(200, 1400, count)})
    assert search(spiked).too_many and find_glitches(spiked) == []
    assert mend(spiked, t, "run a (a.csv)").notes[0].startswith(
        f"run a (a.csv): {count if count <= 7 else '7 or more'} readings jump out and back within one sample")
