"""The rig simulator with every effect off is the linear sampled loop; the batch API is consistent."""

from __future__ import annotations

import control as ct
import numpy as np
import pytest

from grader.errors import SimulationError
from grader.model.effects import EffectSet
from grader.model.linear import closed_loop_tf
from grader.model.params import Controller, RigParams
from grader.model.rig import simulate_rig, simulate_rig_batch
from grader.model.rig_ivp import simulate_rig_ivp
from grader.model.sampled import simulate
from grader.stations import Station

T_END = 0.8


def _step(amplitude: float = 0.2, dt: float = 0.001, end: float = T_END) -> tuple[np.ndarray, np.ndarray]:
    t = np.round(np.arange(0.0, end + 1e-9, dt), 9)
    return t, np.where(t >= 0.1, amplitude, 0.0)


@pytest.fixture(scope="module")
def p(station: Station) -> RigParams:
    return station.params()


@pytest.mark.parametrize(
    "c",
    [Controller(10), Controller(25), Controller(46), Controller(10, Ki=20), Controller(25, Kd=0.02),
     Controller(20, Ki=5, Kd=0.02)],
    ids=lambda c: f"{c.kind}{c.Kp:g}",
)
def test_effects_off_agrees_with_the_linear_sampled_loop(p: RigParams, c: Controller) -> None:
    t, r = _step()
    lin = simulate(p, c, t, r)
    y, u = simulate_rig(p, c, t, r)
    assert np.abs(y - lin.y).max() < 1e-6 * 0.2 * 5  # 1 ppm of the step, x5 for Kp=46's resonance
    assert np.abs(u - lin.u).max() < 1e-4


@pytest.mark.parametrize("feedback", ["volts", "inches"])
def test_effects_off_agrees_on_ramps_in_both_conventions_whatever_the_substeps(p: RigParams, feedback: str) -> None:
    q = p.with_(feedback=feedback)
    t = np.round(np.arange(0.0, T_END + 1e-9, 0.001), 9)
    r = np.where(t >= 0.1, 1.0 * (t - 0.1), 0.0)
    c = Controller(10 * (1 if feedback == "volts" else q.Kpot), Ki=20)
    lin = simulate(q, c, t, r)
    y, _ = simulate_rig(q, c, t, r, substeps=8)
    assert np.abs(y - lin.y).max() < 1e-9


def test_effects_off_with_a_fine_sample_time_approaches_the_continuous_linear_model(p: RigParams) -> None:
    fine = p.with_(sample_time=1e-4)
    t, r = _step(dt=1e-4, end=0.5)
    y, _ = simulate_rig(fine, Controller(25), t, r)
    y_cont = ct.forced_response(closed_loop_tf(p, Controller(25)), T=t, U=r).outputs
    assert np.abs(y - y_cont).max() < 0.01 * 0.2  # 1 % of the step: the hold's T/2 lag is all that is left
    y_coarse, _ = simulate_rig(p, Controller(25), t[::10], r[::10])
    assert np.abs(y - y_cont).max() < 0.2 * np.abs(y_coarse - y_cont[::10]).max()


def test_off_grid_time_base_is_handled_like_the_linear_model(p: RigParams) -> None:
    t, r = _step(dt=0.00037)
    lin = simulate(p, Controller(25), t, r)
    y, u = simulate_rig(p, Controller(25), t, r)
    assert np.abs(y - lin.y).max() < 1e-6 and np.abs(u - lin.u).max() < 1e-4


def test_dac_limits_the_controller_output_to_10_volts(p: RigParams) -> None:
    t, r = _step(amplitude=2.0)
    y, u = simulate_rig(p, Controller(25), t, r)
    assert np.abs(u).max() == pytest.approx(10.0)
    assert np.abs(simulate(p, Controller(25), t, r).u).max() > 40  # the linear model knows no limit
    assert y[-1] == pytest.approx(2.0, abs=1e-3)


def test_batch_rows_equal_single_runs_and_commands_may_differ(p: RigParams) -> None:
    t, r = _step()
    ramp = np.where(t >= 0.1, 0.5 * (t - 0.1), 0.0)
    effects = [EffectSet(), EffectSet.parse(["coulomb_friction:Fc=2lbf"]), EffectSet.parse(["sampling_delay:delay=1.5ms"])]
    params = [p, p.with_(Kce=8e-4), p]
    Y, U = simulate_rig_batch(params, Controller(25), t, np.vstack([r, ramp, r]), effects)
    for row, (q, e, cmd) in enumerate(zip(params, effects, (r, ramp, r))):
        y, u = simulate_rig(q, Controller(25), t, cmd, e)
        np.testing.assert_allclose(Y[row], y, rtol=0, atol=1e-12)
        np.testing.assert_allclose(U[row], u, rtol=0, atol=1e-12)


def test_noise_is_reproducible_from_the_generator(p: RigParams) -> None:
    t, r = _step()
    e = EffectSet.parse(["sensor_noise:sigma=0.001in"])
    a = simulate_rig(p, Controller(25), t, r, e, rng=np.random.default_rng(3))[0]
    b = simulate_rig(p, Controller(25), t, r, e, rng=np.random.default_rng(3))[0]
    c = simulate_rig(p, Controller(25), t, r, e, rng=np.random.default_rng(4))[0]
    assert np.array_equal(a, b) and not np.array_equal(a, c)


def test_fast_integrator_matches_the_solve_ivp_reference_with_all_effects(p: RigParams) -> None:
    effects = EffectSet.parse([
        "coulomb_friction:Fc=2lbf", "viscous_friction:B=0.2lbf*s/in", "valve_saturation:i_max=30mA",
        "valve_deadband:width=0.5mA", "valve_hysteresis:width=0.5mA", "pressure_flow_nonlinearity",
        "sampling_delay:delay=1.4ms", "valve_dynamics:tau=1.5ms,order=2,zeta=0.6",
    ])
    t, r = _step(end=0.5)
    y, u = simulate_rig(p, Controller(30), t, r, effects, substeps=4)
    y_ref, u_ref = simulate_rig_ivp(p, Controller(30), r, effects, rtol=1e-9, atol=1e-11)
    assert np.abs(y - y_ref).max() < 2e-5  # of a 0.2 in step
    assert np.abs(u - u_ref).max() < 2e-3


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"t": np.array([0.0, 0.001]), "r": np.zeros(3)}, "shape"),
        ({"t": np.array([0.0, 0.0, 0.001]), "r": np.zeros(3)}, "increasing"),
        ({"t": np.array([0.0, 0.001, np.nan]), "r": np.zeros(3)}, "finite"),
    ],
)
def test_bad_time_bases_are_rejected(p: RigParams, kwargs: dict, message: str) -> None:
    with pytest.raises(SimulationError, match=message):
        simulate_rig(p, Controller(10), **kwargs)


def test_batch_size_mismatch_and_mixed_sample_times_are_rejected(p: RigParams) -> None:
    t, r = _step(end=0.05)
    with pytest.raises(SimulationError, match="2 controllers for a batch of 3"):
        simulate_rig_batch([p, p, p], [Controller(1), Controller(2)], t, r)
    with pytest.raises(SimulationError, match="same positive sample_time"):
        simulate_rig_batch([p, p.with_(sample_time=0.002)], Controller(1), t, r)
    with pytest.raises(SimulationError, match="2 commands for a batch of 3"):
        simulate_rig_batch([p, p, p], Controller(1), t, np.vstack([r, r]))
