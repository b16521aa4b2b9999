"""The compiled engine against the independent solve_ivp reference and the exact linear loop."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from scipy import linalg

from grader.model import engine, hydraulic
from grader.model.effects import EffectSet
from grader.model.params import Controller, RigParams
from grader.model.rig import simulate_positions, simulate_rig
from grader.model.rig_ivp import simulate_rig_ivp
from grader.model.rig_setup import resolve
from grader.model.sampled import simulate
from grader.stations import Station

T_END = 0.5
CASES = [  # every canonical plant/valve effect; exact-ZOH and RK4 paths, located events
    ("coulomb_friction:Fc=2lbf", Controller(25), 1e-9),
    ("coulomb_friction:Fc=6lbf", Controller(10, Ki=20), 1e-9),
    ("viscous_friction:B=0.3lbf*s/in", Controller(46), 1e-9),
    ("valve_saturation:i_max=25mA", Controller(46), 1e-9),
    ("valve_hysteresis:width=1.5mA", Controller(10, Ki=20), 1e-9),
    ("valve_deadband:width=1mA", Controller(25), 1e-9),
    ("sampling_delay:delay=1.5ms", Controller(46), 1e-9),
    ("valve_dynamics:tau=2ms", Controller(46), 1e-9),
    ("valve_dynamics:tau=1.5ms,order=2,zeta=0.6", Controller(25, Kd=0.02), 1e-9),
    ("pressure_flow_nonlinearity", Controller(46), 2e-7),  # RK4 substeps
]


@pytest.fixture(scope="module")
def p(station: Station) -> RigParams:
    return station.params()


def _step(T: float) -> tuple[np.ndarray, np.ndarray]:
    t = np.round(np.arange(0.0, T_END + 1e-9, T), 9)
    return t, np.where(t >= 0.05, 0.2, 0.0)


@pytest.mark.parametrize(("effect", "controller", "tol"), CASES, ids=[c[0] for c in CASES])
def test_each_effect_agrees_with_the_solve_ivp_reference(p: RigParams, effect: str, controller: Controller,
                                                         tol: float) -> None:
    t, r = _step(p.sample_time)
    effects = EffectSet.parse([effect])
    y, u = simulate_rig(p, controller, t, r, effects)
    y_ref, u_ref = simulate_rig_ivp(p, controller, r, effects, rtol=1e-11, atol=1e-13)
    assert np.abs(y - y_ref).max() < tol  # [in], of a 0.2 in step
    assert np.abs(u - u_ref).max() < 100 * tol  # [V]: u = Kp·Kpot·e


def test_stick_slip_with_a_fractional_delay_agrees_with_the_reference(p: RigParams) -> None:
    effects = EffectSet.parse(["coulomb_friction:Fc=3lbf", "sampling_delay:delay=1.4ms", "valve_hysteresis:width=1mA"])
    t, r = _step(p.sample_time)
    y, _ = simulate_rig(p, Controller(30), t, r, effects)
    y_ref, _ = simulate_rig_ivp(p, Controller(30), r, effects, rtol=1e-11, atol=1e-13)
    assert np.abs(y - y_ref).max() < 1e-9


@pytest.mark.parametrize("c", [Controller(10), Controller(46), Controller(10, Ki=20, Kd=0.02)], ids=str)
def test_linear_case_is_the_exact_sampled_loop_within_1e_6_in(p: RigParams, c: Controller) -> None:
    t, r = _step(p.sample_time)
    y, _ = simulate_rig(p, c, t, r)
    assert np.abs(y - simulate(p, c, t, r).y).max() < 1e-9  # target 1e-6 in
    y_ref, _ = simulate_rig_ivp(p, c, r, rtol=1e-11, atol=1e-13)
    assert np.abs(y - y_ref).max() < 1e-6


def test_rk4_error_falls_at_fourth_order_with_substeps(p: RigParams) -> None:
    t, r = _step(p.sample_time)
    e = EffectSet.parse(["pressure_flow_nonlinearity"])  # smooth: the RK4 path
    ref, _ = simulate_rig_ivp(p, Controller(46), r, e, rtol=1e-12, atol=1e-14, method="DOP853")
    errs = [np.abs(simulate_rig(p, Controller(46), t, r, e, substeps=n)[0] - ref).max() for n in (2, 4)]
    assert 10 < errs[0] / errs[1] < 22  # 2^4 = 16


def test_runs_of_different_lengths_in_one_batch_equal_runs_alone(p: RigParams) -> None:
    r = _step(p.sample_time)[1]
    sets = [EffectSet.parse([e]) for e, _, _ in CASES[:6]]
    ctls = [c for _, c, _ in CASES[:6]]
    cmds = [r, r[:300], 0.5 * r, r, r[:200], r]
    together = simulate_positions([p] * 6, ctls, sets, cmds)
    for c, e, cmd, x in zip(ctls, sets, cmds, together):
        assert x.shape == cmd.shape
        np.testing.assert_array_equal(x, simulate_positions([p], [c], [e], [cmd])[0])


def test_controller_reads_the_given_noise(p: RigParams) -> None:
    r = _step(p.sample_time)[1]
    (x,) = simulate_positions([p], [Controller(25)], [EffectSet()], [r], [np.full(r.size, 0.01)])
    assert x[-1] == pytest.approx(0.19, abs=2e-3)  # a constant reading offset: the loop settles 0.01 in low


@settings(max_examples=15, deadline=None)
@given(st.floats(1e-5, 5e-3), st.sampled_from([0, 1]), st.floats(1e4, 4e4), st.floats(2e-4, 3e-3))
@example(h=0.003626023667346819, stuck=0, bv=10000.0, kce=0.001953125)  # 2e-12 apart: failed a 1e-12 bound once
def test_zero_order_hold_matrices_match_scipy_expm(station: Station, h: float, stuck: int, bv: float,
                                                   kce: float) -> None:
    """The engine's scaling and squaring against scipy's: each row to 1e-10 of its largest entry. Both round by
    about ‖A·h‖·2^s machine epsilons; over 3,000 random draws of this range they differed by at most 3.2e-12 (h of
    3.6 ms, β/Vt 27,000 psi/in³), which a bound of 1e-12 met on most but not all of hypothesis's draws."""
    p = station.params().with_(beta_over_Vt=bv, Kce=kce)
    e = EffectSet.parse(["valve_dynamics:tau=1ms,order=2,zeta=0.5", "viscous_friction:B=0.3lbf*s/in"])
    par = hydraulic.pack(resolve(p, Controller(10), e))[0]
    ac, bc = np.zeros((5, 5)), np.zeros((5, 2))
    hydraulic.linear_system(par, 1 - stuck, ac, bc)
    phi, gam = np.zeros((5, 5)), np.zeros((5, 2))
    engine._zoh(ac, bc, engine._balanced_norm(ac), h, phi, gam)
    big = np.zeros((7, 7))
    big[:5, :5], big[:5, 5:] = ac * h, bc * h
    ref = linalg.expm(big)
    scale = np.abs(ref[:5]).max(axis=1, keepdims=True) + 1e-300
    np.testing.assert_allclose(phi / scale, ref[:5, :5] / scale, rtol=0, atol=1e-10)
    np.testing.assert_allclose(gam / scale, ref[:5, 5:] / scale, rtol=0, atol=1e-10)


def test_a_model_too_stiff_to_step_fails_or_is_skipped_instead_of_running_for_hours(station: Station) -> None:
    """β/Vt of 1e22 psi/in³ (a fit gone wrong) with a nonlinear plant: the public simulator says which run and
    what to check; a fitter's batch gets NaN for that run, at once, and the other runs as usual."""
    from grader.errors import SimulationError
    from grader.model.rig import position_batch

    p = station.params()
    absurd = p.with_(beta_over_Vt=1e22)
    orifice = EffectSet({"pressure_flow_nonlinearity": {}})
    t = np.arange(0.0, 0.5, p.sample_time)
    with pytest.raises(SimulationError, match=r"run 0: .*substeps per sample.*beta_over_Vt"):
        simulate_rig(absurd, Controller(10), t, np.full(t.size, 0.1), orifice)
    r = np.full(t.size, 0.1)
    x = position_batch([p, absurd], [Controller(10)] * 2, [orifice] * 2, [r, r]).run()
    assert np.isnan(x[1]).all() and np.isfinite(x[0]).all()
    assert x[0] == pytest.approx(simulate_positions([p], [Controller(10)], [orifice], [r])[0])


def test_a_stiff_linear_model_without_events_is_stepped_exactly_whatever_the_substep_cap(station: Station) -> None:
    """Exact zero-order hold costs one step per sample at any stiffness: a fitter's cap on RK4 substeps does not
    refuse it (only runs whose cost grows with the stiffness are refused), and nothing changes with the cap."""
    from grader.model.rig import position_batch

    p = station.params()
    stiff = p.with_(beta_over_Vt=p.beta_over_Vt * 50, Kce=p.Kce * 20)
    t = np.arange(0.0, 0.5, p.sample_time)
    r = np.full(t.size, 0.1)
    capped = position_batch([stiff], [Controller(10)], [EffectSet()], [r], max_substeps=2).run()[0]
    assert np.isfinite(capped).all()
    assert np.array_equal(capped, position_batch([stiff], [Controller(10)], [EffectSet()], [r]).run()[0])
    friction = EffectSet({"coulomb_friction": {"Fc": 1.0}})
    assert np.isnan(position_batch([stiff], [Controller(10)], [friction], [r], max_substeps=2).run()[0]).all()


def test_the_engine_runs_as_plain_python_under_numba_disable_jit(p: RigParams) -> None:
    """NUMBA_DISABLE_JIT=1 (numba's own debugging switch) leaves the kernels plain functions: the engine still runs
    (it once raised AttributeError on ``py_func``) and gives the compiled engine's readings."""
    code = ("import json, numpy as np; from grader.model.rig import simulate_rig; from grader.stations import "
            "load_station; from grader.model.params import Controller; from grader.model.effects import EffectSet; "
            "p = load_station('default').params(); t = np.arange(60) * p.sample_time; "
            "y, _ = simulate_rig(p, Controller(25), t, np.where(t > 0.005, 0.1, 0.0), "
            "EffectSet.parse(['coulomb_friction:Fc=2lbf'])); print(json.dumps(y.tolist()))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                          env={**os.environ, "NUMBA_DISABLE_JIT": "1"}, cwd=Path(__file__).parents[2])
    assert done.returncode == 0, done.stderr[-500:]
    t = np.arange(60) * p.sample_time
    friction = EffectSet.parse(["coulomb_friction:Fc=2lbf"])
    y, _ = simulate_rig(p, Controller(25), t, np.where(t > 0.005, 0.1, 0.0), friction)
    assert np.abs(y).max() > 0.01  # the step moved the rig
    np.testing.assert_allclose(json.loads(done.stdout), y, rtol=0, atol=1e-12)


@pytest.mark.parametrize(("effect", "controller", "tol"), CASES, ids=[c[0] for c in CASES])
def test_a_run_replayed_through_its_own_controller_output_moves_as_it_did(p: RigParams, effect: str,
                                                                         controller: Controller, tol: float) -> None:
    """Driven by the controller output its closed loop recorded, a run repeats its positions bit for bit, whatever
    controller it names (the replay reads none); with the output scaled, it does not."""
    from grader.model.rig import position_batch

    t, r = _step(p.sample_time)
    effects = EffectSet.parse([effect])
    y, u = simulate_rig(p, controller, t, r, effects)  # no reading noise: y is the position
    again = position_batch([p], [Controller(1.0, Ki=3.0)], [effects], [r], [u], replay=True).run()[0]
    assert np.array_equal(again, y)
    scaled = position_batch([p], [controller], [effects], [r], [0.9 * u], replay=True).run()[0]
    assert np.abs(scaled - y).max() > 1e-3  # [in]
