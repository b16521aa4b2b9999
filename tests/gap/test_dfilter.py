"""Runs whose controller filters its derivative (Simulink's PID block does by default) are set aside."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.signal import lfilter

from grader.datasets import Dataset
from grader.errors import DiagnosisError
from grader.gap.dfilter import derivative_filter, set_aside
from grader.gap.runs import GapRun, check_gains
from grader.model.params import Controller

T = 0.002  # [s]


def _pd_run(name: str, tau_f: float | None, *, printed: float = 0.0, kd: float = 0.02, seed: int = 0) -> GapRun:
    """A PD step run whose recorded u comes from the manifest's gains with the derivative filtered through a
    first-order lag of ``tau_f`` [s] discretised by the bilinear rule (not the form the detector tries), or
    unfiltered (None); u printed to ``printed`` volts."""
    t = np.arange(0.0, 1.0, T)
    r = np.where(t >= 0.1, 0.2, 0.0)
    y = np.where(t >= 0.1, 0.2 * (1 - np.exp(-(t - 0.1) * 25) * np.cos(40 * (t - 0.1))), 0.0)
    y = y + np.random.default_rng(seed).normal(0.0, 2e-4, t.size)
    c = Controller(8.0, 0.0, kd)
    e = r - y
    diff = np.diff(e, prepend=0.0) / T
    if tau_f is None:
        d = diff
    else:  # Tustin: d_k (2τ + T) = d_{k-1} (2τ − T) + T (diff_k + diff_{k-1})
        d = lfilter([T, T], [2 * tau_f + T, -(2 * tau_f - T)], diff)
    u = np.clip(c.Kp * e + kd * d, -10.0, 10.0)
    if printed:
        u = np.round(u / printed) * printed
    return GapRun(name, "step", c, t, r, y, u, 0.1, 0.2, np.zeros(t.size))


@pytest.mark.parametrize("tau_f", [0.5 * T, 1.7 * T, 5 * T])
def test_a_filtered_derivative_is_found_with_its_time_constant(tau_f: float) -> None:
    found = derivative_filter(_pd_run("pd", tau_f), T, 1.0)
    assert found is not None and abs(found - tau_f) <= max(0.2 * tau_f, 0.4 * T)  # another discretisation


def test_an_unfiltered_derivative_a_p_run_or_a_filter_below_the_print_resolution_is_not_one() -> None:
    assert derivative_filter(_pd_run("pd", None), T, 1.0) is None
    no_u = _pd_run("pd", 3 * T)
    assert derivative_filter(GapRun(no_u.name, no_u.kind, no_u.controller, no_u.t, no_u.r, no_u.y, None, no_u.start,
                                    no_u.scale, no_u.noise), T, 1.0) is None  # no u column: nothing to tell
    assert derivative_filter(_pd_run("pd", None, printed=0.001), T, 1.0) is None
    p_run = _pd_run("p", None, kd=0.0)
    assert derivative_filter(p_run, T, 1.0) is None
    # a derivative so small that its filter moves u by less than the 0.1 V u was printed to
    assert derivative_filter(_pd_run("pd", 2 * T, printed=0.1, kd=2e-4), T, 1.0) is None


def _dataset(runs: list[GapRun]) -> Dataset:
    return Dataset(root=Path("ds"), manifest=None, given={}, calibration=None, flow_test=None,  # type: ignore[arg-type]
                   friction=None, runs=tuple(runs), inputs_sha256="")  # type: ignore[arg-type]


def test_a_filtered_run_is_set_aside_with_a_note_unless_too_few_would_be_left() -> None:
    """The filtered run's u implies gains 1.2 times the manifest's unfiltered law (the gain check refused it before);
    set aside, the others are diagnosed. With only one other run it is kept, and its gains are not checked."""
    filtered, plain = _pd_run("step_pd", 3 * T, kd=0.1), _pd_run("step_kp8", None, kd=0.0, seed=1)
    with pytest.raises(DiagnosisError, match="run step_pd"):
        check_gains([plain, filtered], 1.0, T)
    other = _pd_run("step_kp8b", None, kd=0.0, seed=2)
    runs = [plain, filtered, other]
    ds, kept, notes, unchecked = set_aside(_dataset(runs), runs, 1.0, T)
    assert [r.name for r in kept] == ["step_kp8", "step_kp8b"] and unchecked == frozenset()
    assert [r.name for r in ds.runs] == ["step_kp8", "step_kp8b"]
    assert len(notes) == 1 and notes[0].startswith("run step_pd: its recorded controller output u follows")
    assert "6 ms, 3 samples" in notes[0] and notes[0].endswith("the run is set aside")
    ds, kept, notes, unchecked = set_aside(_dataset([plain, filtered]), [plain, filtered], None, T)
    assert [r.name for r in kept] == ["step_kp8", "step_pd"] and unchecked == {"step_pd"}
    assert "too few other runs to set it aside" in notes[0]
    assert check_gains(kept, None, T, unchecked) == pytest.approx(1.0, rel=1e-3)
