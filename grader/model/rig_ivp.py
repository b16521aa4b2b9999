"""Reference integration of the rig with scipy's ``solve_ivp`` and event location.

An independent, slow path for the rig (one run, scalar code) that shares no physics code
with :mod:`grader.model.rig` or the diagnosis' simulator: it reads the parameters from
:class:`RigParams` and the :class:`EffectSet` itself (its own neutral values, limits and
ADC), and each hold interval is integrated with ``solve_ivp``; stick-slip is handled
exactly with terminal events (velocity reaching zero while slipping, |A·PL| reaching Fc
while stuck). Every canonical effect is modelled, alone or several at once. Used by the
tests to check the fast integrator, and by the diagnosis benchmark to generate its data
(:func:`ivp_run_simulator`), so that a bug shared by generator and fitter cannot inflate
the score.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import RK45, solve_ivp

from grader.model.effects import NO_EFFECTS, EffectSet
from grader.model.params import Controller, RigParams

Array = NDArray[np.float64]
CHATTER_STEP = 1e-6  # [s] event-free step past an event that re-fires at once
DAC_VOLTS = 10.0  # [V] the board's output limit; its ADC spans ±DAC_VOLTS too


@dataclass(frozen=True)
class _Rig:
    """Plain floats of one run (internal units); an effect that is off takes its neutral value."""

    A: float
    M: float
    g: float  # 4·β/Vt [psi/in³]
    Kq: float
    Kce: float
    B: float  # [lbf·s/in] linear B plus viscous_friction
    Fc: float
    half_db: float  # [mA]
    half_hyst: float  # [mA]
    i_lim: float  # [mA]
    inv_Ps: float  # 1/Ps with the orifice law, else 0
    delay: float  # [s]
    tau: float  # [s] spool time constant, 0 = ideal spool
    order: int
    zeta: float
    lsb: float  # [V] ADC step, 0 = not quantised


def _get(effects: EffectSet, name: str, param: str, off: float) -> float:
    return effects.value(name, param) if name in effects else off


def _rig(p: RigParams, e: EffectSet) -> _Rig:
    bits = _get(e, "sensor_quantization", "bits", 0.0)
    return _Rig(
        A=p.A, M=p.M, g=4.0 * p.beta_over_Vt, Kq=p.Kq, Kce=p.Kce, B=p.B + _get(e, "viscous_friction", "B", 0.0),
        Fc=_get(e, "coulomb_friction", "Fc", 0.0), half_db=_get(e, "valve_deadband", "width", 0.0) / 2,
        half_hyst=_get(e, "valve_hysteresis", "width", 0.0) / 2,
        i_lim=min(p.i_max, _get(e, "valve_saturation", "i_max", math.inf)),
        inv_Ps=1.0 / p.supply_pressure if "pressure_flow_nonlinearity" in e else 0.0,
        delay=_get(e, "sampling_delay", "delay", 0.0), tau=_get(e, "valve_dynamics", "tau", 0.0),
        order=int(_get(e, "valve_dynamics", "order", 1.0)), zeta=_get(e, "valve_dynamics", "zeta", 0.7),
        lsb=2.0 * DAC_VOLTS / 2.0**bits if bits else 0.0,
    )


class FixedOrderRK45(RK45):
    """scipy's RK45 with its stages held in long double, so that numpy sums every combination of stages (the
    step, its error, the dense output that locates events) in its own loop, in a fixed order. In float64 it
    calls BLAS, whose kernels round differently from one CPU to another, and the instability run grows any
    difference: a benchmark dataset then depended on the machine that generated it. Give ``first_step``:
    scipy's choice of the first step also goes through BLAS. Long double is 80-bit on x86-64 (a software quad on
    aarch64 Linux, a double on Windows): each architecture is repeatable, with bytes of its own."""

    def __init__(self, *args: object, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        self.K = self.K.astype(np.longdouble)


class _Plant:
    """Right-hand side on the state [x, v, PL, spool current, spool rate]; ``mode`` is +1/−1 (slipping) or 0 (stuck)."""

    def __init__(self, rig: _Rig) -> None:
        self.rig, self.mode, self.i_cmd = rig, 0.0, 0.0

    def flow(self, i_spool: float, pl: float) -> float:
        """Load flow [in³/s] for the spool's current [mA]: deadband, then the orifice law."""
        rig = self.rig
        i = math.copysign(max(abs(i_spool) - rig.half_db, 0.0), i_spool)
        q = rig.Kq * i
        if rig.inv_Ps and i:
            ratio = 1.0 - math.copysign(1.0, i) * pl * rig.inv_Ps
            q *= math.copysign(math.sqrt(abs(ratio)), ratio)
        return q

    def spool_rates(self, sp: float, sd: float) -> tuple[float, float]:
        rig = self.rig
        if not rig.tau:
            return 0.0, 0.0
        if rig.order == 1:
            return (self.i_cmd - sp) / rig.tau, 0.0
        w = 1.0 / rig.tau
        return sd, w * w * (self.i_cmd - sp) - 2.0 * rig.zeta * w * sd

    def rhs(self, _t: float, s: Array) -> list[float]:
        rig = self.rig
        _, v, pl, sp, sd = s
        q = self.flow(sp if rig.tau else self.i_cmd, pl)
        dv = 0.0 if self.mode == 0.0 else (rig.A * pl - rig.B * v - rig.Fc * self.mode) / rig.M
        dsp, dsd = self.spool_rates(sp, sd)
        return [v if self.mode else 0.0, dv, rig.g * (q - rig.Kce * pl - rig.A * v), dsp, dsd]

    def stop(self, _t: float, s: Array) -> float:
        """Slipping: the velocity returns to zero (direction −1 on mode·v)."""
        return self.mode * s[1] if self.mode else 1.0

    def breakaway(self, _t: float, s: Array) -> float:
        """Stuck: the net force reaches Fc (direction +1)."""
        return abs(self.rig.A * s[2]) - self.rig.Fc if self.mode == 0.0 else -1.0

    def after_event(self, s: Array) -> float:
        """New mode after an event: a stopped mass sticks unless |A·PL| > Fc; a stuck one slips."""
        force = self.rig.A * s[2]
        if self.mode and abs(force) <= self.rig.Fc:
            return 0.0
        return math.copysign(1.0, force)


def _events(plant: _Plant) -> list[Callable[[float, Array], float]] | None:
    if plant.rig.Fc <= 0:
        return None

    def stop(t: float, y: Array) -> float:
        return plant.stop(t, y)

    def breakaway(t: float, y: Array) -> float:
        return plant.breakaway(t, y)

    stop.terminal = breakaway.terminal = True  # type: ignore[attr-defined]
    stop.direction, breakaway.direction = -1.0, 1.0  # type: ignore[attr-defined]
    return [stop, breakaway]


def _solve(plant: _Plant, s: Array, t0: float, t1: float, rtol: float, atol: float, method: str,
           events: list[Callable[[float, Array], float]] | None = None) -> Any:
    """``solve_ivp`` over [t0, t1] s; "RK45" is :class:`FixedOrderRK45`, its first step the whole interval."""
    if method != "RK45":
        return solve_ivp(plant.rhs, (t0, t1), s, method=method, rtol=rtol, atol=atol, events=events)
    return solve_ivp(plant.rhs, (t0, t1), s, method=FixedOrderRK45, rtol=rtol, atol=atol, events=events,
                     first_step=t1 - t0)


def _integrate(plant: _Plant, s: Array, t0: float, t1: float, rtol: float, atol: float, method: str) -> Array:
    """Integrate one constant-input interval, restarting at every stick/slip event."""
    events = _events(plant)
    while t1 - t0 > 1e-12:
        sol = _solve(plant, s, t0, t1, rtol, atol, method, events)
        stalled = sol.t[-1] - t0 <= 1e-12
        s, t0 = sol.y[:, -1].astype(float), float(sol.t[-1])
        if sol.status != 1:
            continue
        if plant.mode:
            s[1] = 0.0
        plant.mode = plant.after_event(s)
        if stalled:  # the event fired again at once (force swinging through Fc at v = 0): step past it
            t_next = min(t0 + CHATTER_STEP, t1)
            s = _solve(plant, s, t0, t_next, rtol, atol, method).y[:, -1].astype(float)
            t0 = t_next
            if plant.mode * s[1] < 0:
                s[1] = 0.0
                plant.mode = plant.after_event(s)
    return s


def simulate_rig_ivp(
    params: RigParams,
    controller: Controller,
    r_k: Array,
    effects: EffectSet = NO_EFFECTS,
    *,
    noise: Array | None = None,
    rtol: float = 1e-8,
    atol: float = 1e-10,
    method: str = "RK45",
) -> tuple[Array, Array]:
    """(y_k [in], u_k [V]) on the sample grid for the held command ``r_k`` [in]; ``noise`` [in] per sample.

    Sample k: the pot reading (plus noise, through the ADC) gives the PID output u_k, clipped
    to the DAC; the amplifier current Kamp·u (clipped to the current limit, through the valve's
    backlash) acts ``delay`` later, held until the next sample."""
    rig, T = _rig(params, effects), params.sample_time
    plant = _Plant(rig)
    k_fb = params.k_fb
    Ki_T, Kd_T = controller.Ki * T, controller.Kd / T
    s = np.array([r_k[0], 0.0, 0.0, 0.0, 0.0])
    plant.mode = 0.0 if rig.Fc > 0 else 1.0
    lag = math.floor(rig.delay / T + 1e-9)
    phase = rig.delay - lag * T
    y, u = np.empty(r_k.size), np.empty(r_k.size)
    integ = e_prev = back = 0.0
    for k in range(r_k.size):
        ym = s[0] + (noise[k] if noise is not None else 0.0)
        if rig.lsb:
            ym = round(params.Kpot * ym / rig.lsb) * rig.lsb / params.Kpot
        e = k_fb * (r_k[k] - ym)
        integ += e
        u[k] = min(max(controller.Kp * e + Ki_T * integ + Kd_T * (e - e_prev), -DAC_VOLTS), DAC_VOLTS)
        y[k], e_prev = ym, e
        pieces = [(k - lag - 1, 0.0, phase), (k - lag, phase, T)] if phase else [(k - lag, 0.0, T)]
        for j, start, end in pieces:
            i = min(max(params.Kamp * (u[j] if j >= 0 else 0.0), -rig.i_lim), rig.i_lim)
            back = min(max(back, i - rig.half_hyst), i + rig.half_hyst)
            plant.i_cmd = back
            s = _integrate(plant, s, k * T + start, k * T + end, rtol, atol, method)
    return y, u


def ivp_run_simulator(effects: EffectSet, *, rtol: float = 1e-6, atol: float = 1e-9) -> Callable[..., tuple[Array, Array]]:
    """A run simulator for :func:`grader.synth.make_dataset` (``(p, c, t, r, rng) -> (y, u)``): this
    reference path with ``effects``; the ``sensor_noise`` effect is drawn from ``rng`` and seen by the
    controller."""
    sigma = _get(effects, "sensor_noise", "sigma", 0.0)

    def run(p: RigParams, c: Controller, t: Array, r: Array, rng: np.random.Generator) -> tuple[Array, Array]:
        noise = rng.normal(0.0, sigma, t.size) if sigma > 0 else None
        return simulate_rig_ivp(p, c, r, effects, noise=noise, rtol=rtol, atol=atol)

    return run
