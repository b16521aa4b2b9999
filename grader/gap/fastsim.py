"""The rig model of :mod:`grader.model.rig`, stepped with exact zero-order-hold matrices, for fitting.

Same signal path, parameters (:func:`grader.model.rig_setup.resolve`) and stick-slip
rules as the rig simulator, but the plant — linear between the controller's samples
for every effect acting on the valve's input — is advanced with per-run matrices
e^{A·h} instead of RK4 substeps, and runs of different commands and lengths share one
loop over time (commands padded with their last value). Per sample this is a handful
of vector operations, so hundreds of model points × runs cost little more than one.

State per run: x [in], v [in/s], PL [psi], spool current s [mA]; inputs held over a
step: valve current i [mA], friction force f [lbf], extra flow qx [in³/s]. Coulomb
friction and the orifice law are not linear: they are stepped in ``substeps`` pieces
per sample, friction held at its start-of-step sign with the rig's reversal and
breakaway corrections, the orifice flow taken at the step's midpoint (predictor–
corrector). Supported: any one candidate effect, and combinations except deadband
with spool dynamics, a second-order spool, friction or the orifice law with a
fractional delay, and sensor effects (checked by :func:`supports`).
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import Executor

import numpy as np
from numpy.typing import NDArray

from grader.errors import SimulationError
from grader.model.effects import EffectSet
from grader.model.params import Controller, RigParams
from grader.model.rig_setup import DAC_LIMIT, RigArrays, resolve

Array = NDArray[np.float64]
X, V, P, S = range(4)
NONLINEAR_SUBSTEPS = 2


def supports(effects: EffectSet) -> bool:
    """Whether :func:`simulate` handles this effect set (see module docstring)."""
    names = set(effects.names)
    if names & {"sensor_noise", "sensor_quantization"}:
        return False
    if "valve_dynamics" in names and (effects.value("valve_dynamics", "order") != 1 or "valve_deadband" in names):
        return False
    nonlinear = names & {"coulomb_friction", "pressure_flow_nonlinearity"}
    if nonlinear and (len(nonlinear) > 1 or "sampling_delay" in names):
        return False
    return not ("pressure_flow_nonlinearity" in names and "valve_dynamics" in names)


def _continuous(a: RigArrays, stuck: bool) -> tuple[Array, Array]:
    """(A (n,4,4), B (n,4,3)) of the plant; inputs i, f, qx. Stuck: x and v frozen."""
    n = a.n
    A, B = np.zeros((n, 4, 4)), np.zeros((n, 4, 3))
    if not stuck:
        A[:, X, V] = 1.0
        A[:, V, P] = a.A * a.inv_M
        A[:, V, V] = -a.B * a.inv_M
        A[:, P, V] = -a.g * a.A
        B[:, V, 1] = -a.inv_M
    A[:, P, P] = -a.g * a.Kce
    spool = a.spool > 0
    A[:, P, S] = np.where(spool, a.g * a.Kq, 0.0)
    A[:, S, S] = -a.c0
    B[:, P, 0] = np.where(spool, 0.0, a.g * a.Kq)
    B[:, S, 0] = a.c0
    B[:, P, 2] = a.g
    return A, B


def expm_batch(m: Array) -> Array:
    """e^m for a stack of square matrices (n, k, k): Taylor series of degree 12 with scaling and squaring."""
    norm = float(np.abs(m).sum(axis=2).max()) if m.size else 0.0
    s = max(0, int(np.ceil(np.log2(norm / 0.5)))) if norm > 0 else 0
    a = m / 2.0**s
    out = np.broadcast_to(np.eye(m.shape[1]), m.shape).copy()
    term = out.copy()
    for k in range(1, 13):
        term = term @ a / k
        out += term
    for _ in range(s):
        out = out @ out
    return out


def _zoh(A: Array, B: Array, h: Array) -> tuple[Array, Array]:
    """(Φ (n,4,4), Γ (n,4,3)) of the exact ZOH over step lengths ``h`` (n,); equal rows computed once."""
    n = A.shape[0]
    big = np.zeros((n, 7, 7))
    big[:, :4, :4] = A * h[:, None, None]
    big[:, :4, 4:] = B * h[:, None, None]
    uniq, inverse = np.unique(big.reshape(n, -1), axis=0, return_inverse=True)
    e = expm_batch(uniq.reshape(-1, 7, 7))[inverse.reshape(-1)]
    return e[:, :4, :4], e[:, :4, 4:]


def _mv(m: Array, z: Array) -> Array:
    """Per-run matrix–vector product: m (4,4,n) · z (4,n)."""
    return np.einsum("rcn,cn->rn", m, z)


class _Plant:
    """Advances the plant over one sample; holds the ZOH matrices of a batch."""

    def __init__(self, a: RigArrays) -> None:
        self.a, T = a, a.T
        self.friction, self.orifice = bool(a.Fc.any()), bool(a.inv_Ps.any())
        self.is_nonlinear = self.friction or self.orifice
        lag = np.floor(a.delay / T + 1e-9)
        phase = a.delay - lag * T
        phase[phase < 1e-9 * T] = 0.0
        if self.is_nonlinear and phase.any():
            raise SimulationError("fast simulator: friction or the orifice law with a fractional delay")
        A, B = _continuous(a, stuck=False)
        if self.is_nonlinear:
            self._init_nonlinear(a, A, B)
        else:
            pa, ga = _zoh(A, B, phase)
            pb, gb = _zoh(A, B, T - phase)
            self.phi = np.matmul(pb, pa).transpose(1, 2, 0).copy()
            self.g_a = np.einsum("nrc,nc->rn", pb, ga[:, :, 0])
            self.g_b = gb[:, :, 0].T.copy()
        self.split = bool(phase.any())

    def _init_nonlinear(self, a: RigArrays, A: Array, B: Array) -> None:
        self.m = NONLINEAR_SUBSTEPS
        self.h = a.T / self.m
        h = np.full(a.n, self.h)
        phi, gam = _zoh(A, B, h)
        self.phi, self.gam = phi.transpose(1, 2, 0).copy(), gam.transpose(1, 2, 0).copy()
        phs, gms = _zoh(*_continuous(a, stuck=True), h)
        self.phs, self.gms0 = phs.transpose(1, 2, 0).copy(), gms[:, :, 0].T.copy()
        self.w = np.zeros((3, a.n))  # held inputs: i, friction force, extra orifice flow

    def linear(self, z: Array, i_a: Array | None, i_b: Array) -> Array:
        """Exact step of a linear plant over the sample (inputs i_a before the delayed switch, i_b after)."""
        out = _mv(self.phi, z) + self.g_b * i_b
        return out + self.g_a * i_a if i_a is not None else out

    def nonlinear(self, z: Array, stuck: NDArray[np.bool_], i: Array) -> Array:
        """The sample in ``m`` substeps: friction held at its start-of-step sign, the orifice
        flow taken at mid-step (predicted with the previous substep's value)."""
        a, w = self.a, self.w
        w[0] = i
        if self.orifice:
            c, kqi = np.sign(i) * a.inv_Ps, a.Kq * i
        for _ in range(self.m):
            sgn = np.sign(z[V])
            w[1] = a.Fc * sgn
            new = _mv(self.phi, z) + np.einsum("rcn,cn->rn", self.gam, w)
            if self.orifice:
                ratio = 1.0 - c * (0.5 * (z[P] + new[P]))
                qx = kqi * (np.sign(ratio) * np.sqrt(np.abs(ratio)) - 1.0)
                new += self.gam[:, 2] * (qx - w[2])
                w[2] = qx
            if self.friction:
                new = np.where(stuck, _mv(self.phs, z) + self.gms0 * i, new)
                _reversals(a, z, new, stuck, sgn, self.h)
                _breakaways(a, z, new, stuck, self.h)
            z = new
        return z


def _reversals(a: RigArrays, old: Array, new: Array, stuck: NDArray[np.bool_], sgn: Array, h: float) -> None:
    """Velocity crossed zero inside the step: stop and stick, or reverse (as in the rig simulator)."""
    cross = np.flatnonzero((new[V] * sgn < 0.0) & (a.Fc > 0))
    if cross.size == 0:
        return
    v0, v1, sg = old[V, cross], new[V, cross], sgn[cross]
    rem = (v1 / (v1 - v0)) * h
    fc_m = a.Fc[cross] * a.inv_M[cross]
    v_rev = v1 + 2.0 * fc_m * sg * rem
    sticks = v_rev * sg >= 0.0
    dx = np.where(sticks, -0.5 * v1 * rem, fc_m * sg * rem**2)
    new[X, cross] += dx
    new[P, cross] -= a.g[cross] * a.A[cross] * dx
    new[V, cross] = np.where(sticks, 0.0, v_rev)
    stuck[cross] |= sticks


def _breakaways(a: RigArrays, old: Array, new: Array, stuck: NDArray[np.bool_], h: float) -> None:
    """|A·PL| passed Fc inside the step of a stuck mass: release it (as in the rig simulator)."""
    force = a.A * new[P]
    brk = np.flatnonzero(stuck & (np.abs(force) > a.Fc))
    if brk.size == 0:
        return
    f1, f0, fc = np.abs(force[brk]), np.abs(a.A[brk] * old[P, brk]), a.Fc[brk]
    rem = np.minimum((f1 - fc) / np.maximum(f1 - f0, 1e-300), 1.0) * h
    acc = np.sign(force[brk]) * (f1 - fc) * a.inv_M[brk]
    dx = acc * rem**2 / 6.0
    new[V, brk] = 0.5 * acc * rem
    new[X, brk] += dx
    new[P, brk] -= a.g[brk] * a.A[brk] * dx
    stuck[brk] = False


class _Valve:
    """Amplifier limit, saturation, backlash and (without spool lag) deadband on a held u [V]."""

    def __init__(self, a: RigArrays) -> None:
        self.a, self.h = a, np.zeros(a.n)
        self.hyst, self.db = bool(a.half_hyst.any()), bool(a.half_db.any())

    def __call__(self, u: Array) -> Array:
        a = self.a
        i = np.minimum(np.maximum(a.Kamp * u, -a.i_lim), a.i_lim)
        if self.hyst:
            self.h = np.minimum(np.maximum(self.h, i - a.half_hyst), i + a.half_hyst)
            i = self.h
        if self.db:
            i = np.sign(i) * np.maximum(np.abs(i) - a.half_db, 0.0)
        return i


def _loop(a: RigArrays, r: Array, noise: Array) -> Array:
    """Positions x_k (K, n) of the digital loop for commands ``r`` (K, n); the controller reads x_k + noise_k."""
    K, n = r.shape
    plant, valve = _Plant(a), _Valve(a)
    z = np.zeros((4, n))
    z[X] = r[0]
    stuck = a.Fc > 0
    lag = np.floor(a.delay / a.T + 1e-9).astype(int)
    L = int(lag.max()) + 1
    hist = np.zeros((K + L, n))
    cols = np.arange(n)
    integ, e_prev = np.zeros(n), np.zeros(n)
    Y = np.empty((K, n))
    delayed = bool(lag.any())
    for k in range(K):
        Y[k] = z[X]
        e = a.k_fb * (r[k] - z[X] - noise[k])
        integ += e
        u = np.minimum(np.maximum(a.Kp * e + a.Ki_T * integ + a.Kd_T * (e - e_prev), -DAC_LIMIT), DAC_LIMIT)
        hist[k + L], e_prev = u, e
        i_a = valve(hist[k + L - lag - 1, cols]) if plant.split else None
        i_b = valve(hist[k + L - lag, cols] if delayed else u)
        if not plant.is_nonlinear:
            z = plant.linear(z, i_a, i_b)
            continue
        z = plant.nonlinear(z, stuck, i_b)
    return Y


def _nonlinear(effects: EffectSet) -> bool:
    return bool({"coulomb_friction", "pressure_flow_nonlinearity"} & set(effects.names))


def _batch(params: Sequence[RigParams], controllers: Sequence[Controller], effects: Sequence[EffectSet],
           commands: Sequence[Array], noise: Sequence[Array] | None, idx: list[int]) -> tuple[RigArrays, Array, Array]:
    """Arrays, padded commands and noise (K, n) of the runs ``idx``."""
    a = resolve([params[j] for j in idx], [controllers[j] for j in idx], [effects[j] for j in idx])
    K = max(commands[j].size for j in idx)
    r, nz = np.empty((K, len(idx))), np.zeros((K, len(idx)))
    for col, j in enumerate(idx):
        c = commands[j]
        r[:c.size, col], r[c.size:, col] = c, c[-1]
        if noise is not None:
            nz[:c.size, col] = noise[j]
    return a, r, nz


def _run(a: RigArrays, r: Array, nz: Array) -> Array:
    with np.errstate(all="ignore"):  # a wildly unstable trial model may overflow: its cost says so
        return _loop(a, r, nz)


def simulate(params: Sequence[RigParams], controllers: Sequence[Controller], effects: Sequence[EffectSet],
             commands: Sequence[Array], noise: Sequence[Array] | None = None, *,
             executor: Executor | None = None) -> list[Array]:
    """Position x_k [in] of each run (params[j], controllers[j], effects[j]) for its sampled command
    ``commands[j]`` [in]; the controller reads x_k + ``noise[j][k]`` [in] (default 0).

    Runs with friction or the orifice law and the others go in two loops over time; with an
    ``executor`` (one worker process) the first loop runs there while the second runs here.
    """
    bad = [e for e in effects if not supports(e)]
    if bad:
        raise SimulationError(f"fast simulator: unsupported effect set {', '.join(bad[0].names)}")
    groups = [g for g in ([j for j, e in enumerate(effects) if _nonlinear(e) == flag] for flag in (True, False)) if g]
    batches = [_batch(params, controllers, effects, commands, noise, g) for g in groups]
    pending = executor.submit(_run, *batches[0]) if executor is not None and len(batches) == 2 else None
    local = [_run(*b) for b in (batches[1:] if pending is not None else batches)]
    ys = [pending.result(), *local] if pending is not None else local
    out: list[Array] = [np.empty(0)] * len(commands)
    for idx, Y in zip(groups, ys):
        for col, j in enumerate(idx):
            out[j] = Y[:commands[j].size, col].copy()
    return out
