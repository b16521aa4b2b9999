"""Reference integration of the rig model with scipy's ``solve_ivp`` and event location.

An independent, slow path for the same model as :mod:`grader.model.rig` (one run,
scalar code): each hold interval is integrated with ``solve_ivp``; stick-slip is
handled exactly with terminal events (velocity reaching zero while slipping,
|A·PL| reaching Fc while stuck).  Used by the tests and the benchmark to check the
fast integrator's accuracy and to time "the obvious alternative".
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

from grader.model.effects import NO_EFFECTS, EffectSet
from grader.model.params import Controller, RigParams
from grader.model.rig_setup import DAC_LIMIT, RigArrays, resolve

Array = NDArray[np.float64]
CHATTER_STEP = 1e-6  # [s] event-free step past an event that re-fires at once


class _Plant:
    """Scalar right-hand side for run 0 of ``a``; ``mode`` is +1/−1 (slipping) or 0 (stuck)."""

    def __init__(self, a: RigArrays) -> None:
        self.p = {name: float(getattr(a, name)[0]) for name in (
            "A", "inv_M", "g", "Kq", "Kce", "B", "Fc", "half_db", "inv_Ps", "spool", "c0", "w2", "z2")}
        self.mode, self.i_cmd = 0.0, 0.0

    def rhs(self, _t: float, s: Array) -> list[float]:
        p = self.p
        _, v, pl, sp, sd = s
        i_s = sp if p["spool"] else self.i_cmd
        i_s = math.copysign(max(abs(i_s) - p["half_db"], 0.0), i_s)
        q = p["Kq"] * i_s
        if p["inv_Ps"]:
            ratio = 1.0 - np.sign(i_s) * pl * p["inv_Ps"]
            q *= math.copysign(math.sqrt(abs(ratio)), ratio)
        dv = 0.0 if self.mode == 0.0 else (p["A"] * pl - p["B"] * v - p["Fc"] * self.mode) * p["inv_M"]
        err = self.i_cmd - sp
        dsp = (p["c0"] * err + (p["w2"] > 0) * sd) if p["spool"] else 0.0
        return [v if self.mode else 0.0, dv, p["g"] * (q - p["Kce"] * pl - p["A"] * v), dsp, p["w2"] * err - p["z2"] * sd]

    def stop(self, _t: float, s: Array) -> float:
        """Slipping: the velocity returns to zero (direction −1 on mode·v)."""
        return self.mode * s[1] if self.mode else 1.0

    def breakaway(self, _t: float, s: Array) -> float:
        """Stuck: the net force reaches Fc (direction +1)."""
        return abs(self.p["A"] * s[2]) - self.p["Fc"] if self.mode == 0.0 else -1.0

    def start_mode(self) -> float:
        """At rest at the start: stuck if there is friction, else slipping."""
        return 0.0 if self.p["Fc"] > 0 else 1.0

    def after_event(self, s: Array) -> float:
        """New mode after an event: a stopped mass sticks unless |A·PL| > Fc; a stuck one slips."""
        force = self.p["A"] * s[2]
        if self.mode and abs(force) <= self.p["Fc"]:
            return 0.0
        return math.copysign(1.0, force)


def _integrate(plant: _Plant, s: Array, t0: float, t1: float, rtol: float, atol: float, method: str) -> Array:
    """Integrate one constant-input interval, restarting at every stick/slip event."""
    events = None
    if plant.p["Fc"] > 0:
        def stop(t: float, y: Array) -> float:
            return plant.stop(t, y)

        def breakaway(t: float, y: Array) -> float:
            return plant.breakaway(t, y)

        stop.terminal = breakaway.terminal = True  # type: ignore[attr-defined]
        stop.direction, breakaway.direction = -1.0, 1.0  # type: ignore[attr-defined]
        events = [stop, breakaway]
    while t1 - t0 > 1e-12:
        sol = solve_ivp(plant.rhs, (t0, t1), s, method=method, rtol=rtol, atol=atol, events=events)
        stalled = sol.t[-1] - t0 <= 1e-12
        s, t0 = sol.y[:, -1].copy(), float(sol.t[-1])
        if sol.status != 1:
            continue
        if plant.mode:
            s[1] = 0.0
        plant.mode = plant.after_event(s)
        if stalled:  # the event fired again at once (force swinging through Fc at v = 0): step past it
            t_next = min(t0 + CHATTER_STEP, t1)
            s = solve_ivp(plant.rhs, (t0, t_next), s, method=method, rtol=rtol, atol=atol).y[:, -1].copy()
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
    """(y_k [in], u_k [V]) on the sample grid for the held command ``r_k`` [in]; ``noise`` [in] per sample."""
    a = resolve(params, controller, effects)
    plant, T = _Plant(a), a.T
    g = {n: float(getattr(a, n)[0]) for n in ("Kp", "Ki_T", "Kd_T", "k_fb", "Kpot", "lsb", "Kamp", "i_lim",
                                               "half_hyst", "delay")}
    s = np.array([r_k[0], 0.0, 0.0, 0.0, 0.0])
    plant.mode = plant.start_mode()
    lag = math.floor(g["delay"] / T + 1e-9)
    phase = g["delay"] - lag * T
    y, u = np.empty(r_k.size), np.empty(r_k.size)
    integ = e_prev = back = 0.0
    for k in range(r_k.size):
        ym = s[0] + (noise[k] if noise is not None else 0.0)
        if g["lsb"]:
            ym = round(g["Kpot"] * ym / g["lsb"]) * g["lsb"] / g["Kpot"]
        e = g["k_fb"] * (r_k[k] - ym)
        integ += e
        u[k] = min(max(g["Kp"] * e + g["Ki_T"] * integ + g["Kd_T"] * (e - e_prev), -DAC_LIMIT), DAC_LIMIT)
        y[k], e_prev = ym, e
        pieces = [(k - lag - 1, 0.0, phase), (k - lag, phase, T)] if phase else [(k - lag, 0.0, T)]
        for j, start, end in pieces:
            i = min(max(g["Kamp"] * (u[j] if j >= 0 else 0.0), -g["i_lim"]), g["i_lim"])
            back = min(max(back, i - g["half_hyst"]), i + g["half_hyst"])
            plant.i_cmd = back
            s = _integrate(plant, s, k * T + start, k * T + end, rtol, atol, method)
    return y, u
