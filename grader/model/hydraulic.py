"""The hydraulic servo positioner's equations: the one plant the compiled engine integrates.

This module is the plant's side of the engine's narrow interface (see
:mod:`grader.model.engine` and docs/explanation/engine.md). A plant provides:

* ``N_STATES`` and :func:`pack` — the per-run parameter row (float64) from
  :class:`grader.model.rig_setup.RigArrays`;
* ``rhs(z, par, i, mode, out)`` — d(state)/dt for a held input ``i`` [mA] in a mode;
* ``is_linear(par)``, ``linear_system(par, mode, Ac, Bc)`` and ``linear_input(par, i, mode, w)``
  — where the flow is linear between events (exact zero-order hold), the matrices of
  dz/dt = Ac·z + Bc·w with ``N_INPUTS`` held inputs;
* ``has_events(par)``, ``event_value(z, par, mode)`` (an event where it turns negative),
  ``after_event(z, par, mode)`` (the new mode) and ``initial_mode(par)``.

State: x [in], v [in/s], PL [psi], spool current s [mA], spool rate [mA/s]. Merritt's
lumped form, g = 4·β/Vt: dPL/dt = g·(QL − Kce·PL − A·v), M·dv/dt = A·PL − B·v − friction,
QL = Kq·i_s [·orifice law], i_s the spool current less the deadband. Mode +1/−1: slipping
with Coulomb friction Fc·mode; 0: stuck (x, v frozen) while |A·PL| <= Fc. All functions are
numba-compiled (``cache=True``, no fastmath).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from grader.model.rig_setup import RigArrays

X, V, P, S, SD = range(5)
N_STATES, N_INPUTS = 5, 2  # inputs of the linear form: valve/spool current [mA], friction force [lbf]
# parameter row
A_, INV_M, G, KQ, KCE, B_, FC, HALF_DB, INV_PS, SPOOL, C0, ORDER2, W2, Z2 = range(14)
N_PAR = 14


def pack(a: RigArrays) -> NDArray[np.float64]:
    """Per-run parameter rows (n, N_PAR) in internal units."""
    cols = (a.A, a.inv_M, a.g, a.Kq, a.Kce, a.B, a.Fc, a.half_db, a.inv_Ps, a.spool, a.c0, a.order2, a.w2, a.z2)
    return np.ascontiguousarray(np.stack(cols, axis=1), dtype=np.float64)


@njit(cache=True, inline="always")
def _deadband(i: float, half: float) -> float:
    if half <= 0.0:
        return i
    return math.copysign(max(abs(i) - half, 0.0), i)


@njit(cache=True)
def rhs(z, par, i, mode, out):  # noqa: ANN001, ANN201 (numba)
    """d(state)/dt into ``out`` for held current ``i`` [mA] in ``mode``."""
    spool = par[SPOOL] > 0.0
    i_s = _deadband(z[S] if spool else i, par[HALF_DB])
    q = par[KQ] * i_s
    if par[INV_PS] > 0.0:
        ratio = 1.0 - np.sign(i_s) * z[P] * par[INV_PS]
        q *= math.copysign(math.sqrt(abs(ratio)), ratio)
    if mode == 0:
        out[X], out[V] = 0.0, 0.0
    else:
        out[X] = z[V]
        out[V] = (par[A_] * z[P] - par[B_] * z[V] - par[FC] * mode) * par[INV_M]
    out[P] = par[G] * (q - par[KCE] * z[P] - par[A_] * z[V])
    if spool:
        err = i - z[S]
        out[S] = par[C0] * err + par[ORDER2] * z[SD]
        out[SD] = par[W2] * err - par[Z2] * z[SD]
    else:
        out[S], out[SD] = 0.0, 0.0


@njit(cache=True)
def is_linear(par) -> bool:  # noqa: ANN001
    """Linear between events: no orifice law, no deadband acting on a moving spool."""
    return par[INV_PS] == 0.0 and not (par[SPOOL] > 0.0 and par[HALF_DB] > 0.0)


@njit(cache=True)
def linear_system(par, mode, Ac, Bc):  # noqa: ANN001, ANN201, N803
    """Fill (zeroed) Ac (N_STATES²) and Bc (N_STATES×N_INPUTS) of the linear form in ``mode``."""
    if mode != 0:
        Ac[X, V] = 1.0
        Ac[V, P] = par[A_] * par[INV_M]
        Ac[V, V] = -par[B_] * par[INV_M]
        Ac[P, V] = -par[G] * par[A_]
        Bc[V, 1] = -par[INV_M]
    Ac[P, P] = -par[G] * par[KCE]
    if par[SPOOL] > 0.0:
        Ac[P, S] = par[G] * par[KQ]
        Ac[S, S] = -par[C0]
        Ac[S, SD] = par[ORDER2]
        Ac[SD, S] = -par[W2]
        Ac[SD, SD] = -par[Z2]
        Bc[S, 0] = par[C0]
        Bc[SD, 0] = par[W2]
    else:
        Bc[P, 0] = par[G] * par[KQ]


@njit(cache=True, inline="always")
def linear_input(par, i, mode, w):  # noqa: ANN001, ANN201
    """Held inputs ``w`` of the linear form for current ``i`` [mA] in ``mode``."""
    w[0] = i if par[SPOOL] > 0.0 else _deadband(i, par[HALF_DB])
    w[1] = par[FC] * mode


@njit(cache=True)
def has_events(par) -> bool:  # noqa: ANN001
    """Stick-slip friction is on."""
    return par[FC] > 0.0


@njit(cache=True)
def initial_mode(par) -> int:  # noqa: ANN001
    """At rest at the start: stuck with friction, else slipping."""
    return 0 if par[FC] > 0.0 else 1


@njit(cache=True, inline="always")
def event_value(z, par, mode) -> float:  # noqa: ANN001
    """Slipping: mode·v (the mass stops where it reaches 0); stuck: Fc − |A·PL| (breakaway)."""
    if mode != 0:
        return mode * z[V]
    return par[FC] - abs(par[A_] * z[P])


@njit(cache=True)
def after_event(z, par, mode) -> int:  # noqa: ANN001
    """The mode after an event (a stopping mass gets v = 0): it sticks unless |A·PL| > Fc."""
    force = par[A_] * z[P]
    if mode != 0:
        z[V] = 0.0
        if abs(force) <= par[FC]:
            return 0
    return 1 if force > 0.0 else -1
