"""The valve's null current in the runs (grader.gap.null): read where the runs rest, held in the model's inputs."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from grader.datasets import load
from grader.gap import null as null_mod
from grader.gap.bench import with_null
from grader.gap.backend import Backend, Point
from grader.gap.diagnose import analyse
from grader.gap.replay import ReplayObjective
from grader.gap.runs import GapRun, prepare_runs
from grader.model.effects import EffectSet
from grader.model.params import Controller, RigParams
from grader.model.rig_ivp import ivp_run_simulator
from grader.stations import Station
from grader.synth import make_dataset

from .conftest import SIGMA, short_plan

INDEPENDENT = Path(__file__).parent / "data" / "independent_null"


def _runs(station: Station, tmp_path: Path, i0: float) -> tuple[list[GapRun], RigParams]:
    quiet = station.model_copy(update={"noise": {**station.noise, "position": "0 in"}, "effects": {}})
    sim = ivp_run_simulator(EffectSet({"sensor_noise": {"sigma": SIGMA}}))
    ds = load(make_dataset(quiet, tmp_path / "ds", seed=7, runs=short_plan(station),
                           run_simulator=with_null(sim, i0)))
    return prepare_runs(ds, ds.given["sample_time"])[1], quiet.params()


@pytest.mark.parametrize("i0", [0.03, -0.1])
def test_the_null_is_read_where_the_runs_rest_and_the_model_then_follows_them(station: Station, tmp_path: Path,
                                                                              i0: float) -> None:
    runs, p = _runs(station, tmp_path, i0)
    null = null_mod.estimate(runs, p.Kamp, p.k_fb)
    assert null is not None and abs(null.i0 - i0) < 3.0 * null.se and null.se < 0.1 * abs(i0)
    held = null_mod.held(runs, null, p.Kamp, p.k_fb)
    # the true rig's model against the readings, with and without the null in its inputs (the instability run aside:
    # its growth magnifies any difference); a PI run's integrator holds the null either way
    without, with_ = (Backend(rs).all_runs([Point(p)])[0] for rs in (runs, held))
    for run, a, b in zip(runs, without, with_):
        if run.kind != "instability" and not run.controller.Ki:
            rms_with, rms_without = (float(np.sqrt(np.mean((x - run.y) ** 2))) for x in (b, a))
            assert rms_with < 1.2 * SIGMA and rms_without > rms_with, run.name
            if run.controller.Kp == 10.0:  # the least gain: the largest shift, 1.5 mil at 0.03 mA
                assert rms_without > 1.5 * rms_with
    # replayed through the recorded output (which lacks the null), the model follows each run to the noise; the
    # replay's objective takes out a drift, so the null's own mark is checked apart: driven open loop, the valve's
    # current Kamp·u − i0 moves the piston i0·Kq/A slower than the recorded u alone would
    replayed, bare = (Backend(rs, replay=True).all_runs([Point(p)])[0] for rs in (held, runs))
    for run, x, x0 in zip(held, replayed, bare):
        if run.kind != "instability":
            assert float(np.sqrt(np.mean(ReplayObjective(run, SIGMA).residual(x) ** 2))) < 1.5, run.name
            late = run.t > run.t[-1] / 2
            slope = np.polyfit(run.t[late], (x - x0)[late], 1)[0]
            assert slope == pytest.approx(-i0 * p.Kq / p.A, rel=0.05), run.name


def test_the_held_null_shifts_a_p_run_s_command_by_what_holds_it_at_any_gain() -> None:
    """The valve sees Kamp·u − i0: a P loop at gain Kp reads a command i0/(Kamp·Kp·k_fb) lower; a PI loop's integrator
    holds it (no shift); a gain tried apart (the augmented critical gain's search) gets its own shift."""
    null = null_mod.Null(0.05, 0.001, ("s",))
    p_run, pi_run = _resting("p", 0.01), replace(_resting("i", 0.01), controller=Controller(10.0, Ki=5.0))
    held_p, held_pi = null_mod.held([p_run, pi_run], null, 5.0, 0.4)
    assert held_p.null_u == held_pi.null_u == pytest.approx(-0.01)
    assert held_p.command_shift == pytest.approx(-0.05 / (5.0 * 10.0 * 0.4)) and held_pi.command_shift == 0.0
    assert replace(held_p, controller=Controller(40.0)).command_shift == pytest.approx(held_p.command_shift / 4.0)
    assert null_mod.held([p_run], null, 5.0, None) == [p_run] == null_mod.held([p_run], None, 5.0, 0.4)


def test_runs_that_rest_at_their_commands_hold_no_null(station: Station, tmp_path: Path) -> None:
    runs, p = _runs(station, tmp_path, 0.0)
    assert null_mod.estimate(runs, p.Kamp, p.k_fb) is None
    assert null_mod.held(runs, None, p.Kamp, p.k_fb) == runs


def _resting(name: str, u_rest: float, kp: float = 10.0, seed: int = 0, u_end: float | None = None) -> GapRun:
    """A P step run that rests at controller output ``u_rest`` [V] before its command at 0.1 s and, settled again
    from 0.3 s, at ``u_end`` (None: the same)."""
    t = np.arange(0.0, 0.5, 0.001)
    u = np.where(t < 0.1, u_rest, np.where(t < 0.3, 0.5, u_rest if u_end is None else u_end))
    u = u + np.random.default_rng(seed).normal(0.0, 1e-3, t.size)
    r = np.where(t < 0.1, 0.0, 0.2)
    return GapRun(name, "step", Controller(kp), t, r, np.zeros(t.size), u, 0.1, 0.1, np.zeros(t.size))


def test_rests_that_disagree_are_no_null() -> None:
    """A rig held off by friction rests wherever its last motion stopped, run by run."""
    agree = [_resting(f"s{k}", -0.01, seed=k) for k in range(3)]
    null = null_mod.estimate(agree, 5.0, 1.0)
    assert null is not None and null.i0 == pytest.approx(-0.05, abs=3 * null.se)  # Kamp·u at rest
    assert null.rests == tuple(f"s{k} {where}" for k in range(3) for where in ("before its command", "at its end"))
    assert null_mod.estimate([*agree[:2], _resting("s2", 0.01, seed=2)], 5.0, 1.0) is None
    assert null_mod.estimate([], 5.0, 1.0) is None and null_mod.estimate(agree, 5.0, None) is None
    short = replace(agree[0], start=0.005)  # rests 5 samples: too few
    assert null_mod._reading(short, short.t < short.start, 5.0, 1.0, 0.0) is None


def test_a_null_finer_than_the_readings_lattice_is_none() -> None:
    """Quantised readings at rest average to up to half a step off where the rig is: a null that moves no P run's
    rest by half a step is below what they resolve (a benchmark rig with a 14-bit ADC and no null read −0.004 mA)."""
    agree = [_resting(f"s{k}", -0.01, seed=k) for k in range(3)]  # i0 = 0.05 mA: 1 mil off at Kp 10, Kamp 5, k_fb 1
    assert null_mod.estimate(agree, 5.0, 1.0, step=0.0019) is not None
    assert null_mod.estimate(agree, 5.0, 1.0, step=0.0021) is None


def test_readings_constant_at_rest_have_the_lattice_s_standard_error_or_give_none() -> None:
    """A quiet rig on an ADC's lattice reads the same count at rest: its mean is known to the lattice step/√12,
    not to the round-off of a zero spread; without a lattice known, such a rest gives no reading."""
    t = np.arange(0.0, 0.1, 0.001)
    still = GapRun("s", "step", Controller(10.0), t, np.zeros(t.size), np.full(t.size, -0.001), None, 0.1, 0.1,
                   np.zeros(t.size))
    rest = t < 0.1
    i0, se = null_mod._reading(still, rest, 5.0, 1.0, 0.001)  # type: ignore[misc]
    assert i0 == pytest.approx(0.05) and se == pytest.approx(5.0 * 10.0 * 0.001 / np.sqrt(12.0))
    assert null_mod._reading(still, rest, 5.0, 1.0, 0.0) is None
    with_nan = _resting("n", -0.01)
    u = with_nan.u.copy()
    u[5] = np.nan
    assert null_mod._reading(replace(with_nan, u=u), with_nan.t < 0.1, 5.0, 1.0, 0.0) is not None


def test_a_step_run_whose_command_moves_at_its_end_has_no_end_rest() -> None:
    run = _resting("s", -0.01)
    moving = replace(run, r=np.where(run.t < 0.45, run.r, 0.3))
    assert [name for name, _, _ in null_mod._rests(moving)] == ["s before its command"]


def test_a_step_that_ends_held_on_the_other_side_of_its_rest_is_no_null() -> None:
    """Friction holds a P loop off its command on the side it came from: a step run resting before its command on
    one side of the command and after the step on the other disagrees with itself, which a null cannot do (an
    independent simulator's Coulomb rig with a +0.018 mA null read −0.014 mA from its rests alone, and its
    Coulomb friction was lost)."""
    runs = [_resting(f"s{k}", -0.01, seed=k, u_end=0.01) for k in range(3)]
    assert null_mod.estimate(runs, 5.0, 1.0) is None
    assert null_mod.estimate([replace(r, kind="ramp") for r in runs], 5.0, 1.0) is not None  # no end rest read


def test_a_rest_still_settling_and_an_instability_run_give_no_reading() -> None:
    run = _resting("s", -0.01)
    rest = run.t < run.start
    settling = replace(run, u=np.where(rest, np.linspace(-0.03, 0.0, run.t.size), run.u))
    assert null_mod._reading(run, rest, 5.0, 1.0, 0.0) is not None
    assert null_mod._reading(settling, rest, 5.0, 1.0, 0.0) is None
    assert null_mod._rests(replace(run, kind="instability")) == []
    assert [name for name, _, _ in null_mod._rests(run)] == ["s before its command", "s at its end"]
    assert [name for name, _, _ in null_mod._rests(replace(run, controller=Controller(10.0, Ki=5.0)))] == \
        ["s before its command"]


def test_a_p_run_without_u_gives_the_null_from_its_position() -> None:
    run = _resting("s", 0.0)
    y = np.where(run.t < 0.1, 0.002, 0.2) + np.random.default_rng(3).normal(0.0, 1e-4, run.t.size)
    p_run = replace(run, u=None, y=y)
    rest = run.t < run.start
    i0, se = null_mod._reading(p_run, rest, 5.0, 0.4, 0.0)  # type: ignore[misc]
    assert i0 == pytest.approx(-5.0 * 10.0 * 0.4 * 0.002, abs=3 * se)  # resting above its command: less current
    assert null_mod._reading(replace(p_run, controller=Controller(10.0, Ki=5.0)), rest, 5.0, 0.4, 0.0) is None


def test_an_independent_simulators_null_is_no_viscous_friction() -> None:
    """A rig with no effect from a simulator that shares no code with grader, whose valve passes no flow at
    +0.0167 mA in the runs: the runs' loop gain came out 0.52 % below the flow test's (3.1 standard errors) without the
    null, and viscous friction B = 0.12 lbf·s/in was named."""
    truth = json.loads(INDEPENDENT.with_suffix(".truth.json").read_text())
    d = analyse(INDEPENDENT).diagnosis
    assert d.verdict.effect == "none" and d.verdict.second_effect is None
    assert d.valve_null is not None and d.valve_null.unit == "mA" and d.valve_null.interval is not None
    lo, hi = d.valve_null.interval
    assert 0.0 < lo < truth["no_flow_current_mA"] < hi
    assert any(f"no flow at {d.valve_null.value:.3g} mA" in n for n in d.notes)
    assert d.loop_gain is not None and abs(d.loop_gain.deficit_z) < 2.5


def test_an_independent_rig_a_tenth_of_a_milliamp_off_its_null_is_no_coulomb_friction() -> None:
    """The same simulator's rig with no effect, regenerated with its valve passing no flow at +0.1 mA: without the
    null in the model, Coulomb friction was named (the P runs rest 0.3 to 1.5 mils behind their commands)."""
    root = INDEPENDENT.with_name("independent_null_large")
    truth = json.loads(root.with_suffix(".truth.json").read_text())
    d = analyse(root).diagnosis
    assert d.verdict.effect == "none" and d.verdict.second_effect is None
    assert d.valve_null is not None and d.valve_null.interval is not None
    lo, hi = d.valve_null.interval
    assert lo < truth["no_flow_current_mA"] < hi


def test_a_coulomb_rig_held_by_its_friction_reads_no_null_and_keeps_its_friction() -> None:
    """The same simulator's Coulomb rig (Fc = 1.57 lbf, no flow at −0.018 mA): friction holds its P runs on either
    side of their commands, before the steps and after them. Read from the rests before the commands alone, the
    null came out +0.014 mA, and with it held the friction was lost (a current limit was named). No null is read
    from the rests; it is fitted with every candidate instead (grader.gap.null.free), and covers the simulator's.
    Fc comes out 1.24 lbf either way: the simulator's friction is a tanh of speed (band 0.008 in/s), which
    grips less than a Coulomb level of its Fc near rest. With the null fitted, the fit's mean square halves and the
    interval (1.06 to 1.43 lbf) no longer reaches 1.57 lbf."""
    root = INDEPENDENT.with_name("independent_coulomb_null")
    truth = json.loads(root.with_suffix(".truth.json").read_text())
    d = analyse(root).diagnosis
    assert not any("read where the runs rest" in n for n in d.notes)
    assert d.valve_null is not None and d.valve_null.interval is not None
    assert d.valve_null.interval[0] < truth["no_flow_current_mA"] < d.valve_null.interval[1]
    assert d.verdict.effect == "coulomb_friction" and d.verdict.second_effect is None
    fc = next(c for c in d.candidates if c.effect == "coulomb_friction").params["Fc"]
    assert fc.interval is not None and fc.interval[0] < fc.value < fc.interval[1]
    assert fc.value == pytest.approx(truth["effects"]["coulomb_friction"]["Fc_lbf"], rel=0.25)
