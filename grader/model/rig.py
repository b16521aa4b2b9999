"""The nonlinear rig simulator: the real closed loop, unmodelled effects included.

Signal path at every sample instant t_k = k·T (the rig's digital loop)::

    pot -> [sensor_noise] -> [sensor_quantization, ADC ±10 V] -> y_k (recorded and fed back)
    e_k = k_fb·(r_k − y_k);  u_k = Kp e_k + Ki T Σ e_j + Kd (e_k − e_{k−1})/T, clipped to the DAC's ±10 V
    u_k held (ZOH) [+ sampling_delay] -> amplifier i = Kamp·u, clipped to ±i_max of RigParams
      -> [valve_saturation] -> [valve_hysteresis] -> [valve_dynamics] -> [valve_deadband]
      -> flow QL = Kq·i_s [·orifice law: pressure_flow_nonlinearity] − Kce·PL

Plant (Merritt's lumped form, g = 4·β/Vt): dPL/dt = g·(QL − A·v),
M·dv/dt = A·PL − B·v − friction, dx/dt = v; ``coulomb_friction`` is stick-slip:
a mass at rest stays at rest while |A·PL| <= Fc.  With no effect on, this is exactly
the linear model of :mod:`grader.model.sampled` (same law, instants, ZOH, start at
rest at y = r[0]).

Integration: classical RK4 with a fixed number of substeps per sample (vectorised
over the batch; the Python loop runs over time only); a fractional delay puts a
step boundary where the delayed output switches.  Friction is held at its
start-of-step sign; a velocity reversal inside a step is located by linear
interpolation and the state corrected (stop and stick, or reverse with the
friction flipped), and so is a breakaway (|A·PL| passing Fc) of a stuck mass.
The recorded u is the controller output at its sample instant (before any delay).

API::

    y, u = simulate_rig(params, controller, t, r, effects, rng=rng)          # one run: y [in], u [V]
    Y, U = simulate_rig_batch(params_list, controller, t, r, effects_list)   # shape (n, len(t))
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from grader.errors import SimulationError
from grader.model.effects import NO_EFFECTS, EffectSet
from grader.model.params import Controller, RigParams
from grader.model.rig_setup import DAC_LIMIT, RigArrays, resolve

Array = NDArray[np.float64]
X, V, P, S, SD = range(5)  # state rows: position, velocity, load pressure, spool, spool rate


def _derivative(st: Array, out: Array, a: RigArrays, i_cmd: Array, ff: Array | float, slip: Array | float,
                flags: tuple[bool, bool, bool]) -> Array:
    """d(state)/dt into ``out``; ``ff`` = friction force [lbf], ``slip`` = 0 where stuck;
    ``flags`` = (spool dynamics, deadband, orifice law) present in the batch."""
    spool, deadband, orifice = flags
    v, pl = st[V], st[P]
    i_s = st[S] if spool else i_cmd
    if deadband:
        i_s = np.sign(i_s) * np.maximum(np.abs(i_s) - a.half_db, 0.0)
    q = a.Kq * i_s
    if orifice:
        ratio = 1.0 - np.sign(i_s) * pl * a.inv_Ps
        q = q * np.sign(ratio) * np.sqrt(np.abs(ratio))
    out[X] = v
    out[V] = (a.A * pl - a.B * v - ff) * a.inv_M * slip
    out[P] = a.g * (q - a.Kce * pl - a.A * v)
    if spool:
        err = i_cmd - st[S]
        out[S] = a.c0 * err + a.order2 * st[SD]
        out[SD] = a.w2 * err - a.z2 * st[SD]
    return out


def _at(h: float | Array, idx: NDArray[np.intp]) -> float | Array:
    """A step length shared by the batch, or the entries ``idx`` of per-run lengths."""
    return h[idx] if isinstance(h, np.ndarray) else h


class _Integrator:
    """RK4 substeps with stick-slip handling; holds the buffers for one batch."""

    def __init__(self, a: RigArrays, n_states: int) -> None:
        self.a = a
        self.flags = (n_states > P + 1, bool(a.half_db.any()), bool(a.inv_Ps.any()))
        self.k = [np.empty((n_states, a.n)) for _ in range(4)]
        self.friction = bool(a.Fc.any())

    def step(self, st: Array, stuck: NDArray[np.bool_], i_cmd: Array, h: float | Array) -> Array:
        """One RK4 step of length ``h`` [s]; updates ``stuck`` in place, returns the new state."""
        a, (k1, k2, k3, k4), f = self.a, self.k, _derivative
        ff: Array | float = 0.0
        slip: Array | float = 1.0
        sgn = np.zeros(0)
        if self.friction:
            sgn = np.sign(st[V])  # slipping masses move (a released one gets its first v in _breakaways)
            ff, slip = a.Fc * sgn, (~stuck).astype(np.float64)
        f(st, k1, a, i_cmd, ff, slip, self.flags)
        f(st + (0.5 * h) * k1, k2, a, i_cmd, ff, slip, self.flags)
        f(st + (0.5 * h) * k2, k3, a, i_cmd, ff, slip, self.flags)
        f(st + h * k3, k4, a, i_cmd, ff, slip, self.flags)
        new = st + (h / 6.0) * (k1 + 2.0 * (k2 + k3) + k4)
        if self.friction:
            self._reversals(st, new, stuck, sgn, h)
            self._breakaways(st, new, stuck, h)
        return new

    def _reversals(self, old: Array, new: Array, stuck: NDArray[np.bool_], sgn: Array, h: float | Array) -> None:
        """Velocity crossed zero inside the step: stop and stick, or reverse with the friction flipped."""
        cross = np.flatnonzero((new[V] * sgn < 0.0) & (self.a.Fc > 0))
        if cross.size == 0:
            return
        a = self.a
        v0, v1, sg = old[V, cross], new[V, cross], sgn[cross]
        rem = (v1 / (v1 - v0)) * _at(h, cross)  # time since the crossing
        fc_m = a.Fc[cross] * a.inv_M[cross]
        v_rev = v1 + 2.0 * fc_m * sg * rem  # velocity had friction flipped at the crossing
        sticks = v_rev * sg >= 0.0
        dx = np.where(sticks, -0.5 * v1 * rem, fc_m * sg * rem**2)
        new[X, cross] += dx
        new[P, cross] -= a.g[cross] * a.A[cross] * dx
        new[V, cross] = np.where(sticks, 0.0, v_rev)
        stuck[cross] |= sticks

    def _breakaways(self, old: Array, new: Array, stuck: NDArray[np.bool_], h: float | Array) -> None:
        """|A·PL| passed Fc inside the step of a stuck mass: release it at the interpolated instant,
        with the motion a linearly growing excess force gives over the rest of the step."""
        a = self.a
        force = a.A * new[P]
        brk = np.flatnonzero(stuck & (np.abs(force) > a.Fc))
        if brk.size == 0:
            return
        f1, f0, fc = np.abs(force[brk]), np.abs(a.A[brk] * old[P, brk]), a.Fc[brk]
        # fraction of the step since |force| passed Fc (all of it if it was already above: a mass
        # that stuck at a reversal while the force exceeded Fc breaks away at once)
        frac = np.where(f0 >= fc, 1.0, np.clip((f1 - fc) / np.maximum(f1 - f0, 1e-300), 0.0, 1.0))
        rem = frac * _at(h, brk)
        acc = np.sign(force[brk]) * (f1 - fc) * a.inv_M[brk]  # excess acceleration at the step's end
        dx = acc * rem**2 / 6.0
        new[V, brk] = 0.5 * acc * rem
        new[X, brk] += dx
        new[P, brk] -= a.g[brk] * a.A[brk] * dx
        stuck[brk] = False


def _measure(a: RigArrays, x: Array, noise: Array | None) -> Array:
    """What the ADC reports, as a position [in]."""
    y = x if noise is None else x + noise
    if a.quantised:
        y = np.where(a.lsb > 0, np.round(y * a.counts_per_in) / a.counts_per_in, y)
    return y


class _Valve:
    """Amplifier, saturation and backlash: the current reaching the spool for a held u [V]."""

    def __init__(self, a: RigArrays) -> None:
        self.a, self.h = a, np.zeros(a.n)

    def __call__(self, u: Array) -> Array:
        i = np.clip(self.a.Kamp * u, -self.a.i_lim, self.a.i_lim)
        if self.a.half_hyst.any():
            self.h = np.clip(self.h, i - self.a.half_hyst, i + self.a.half_hyst)
            return self.h
        return i


class _Schedule:
    """Per sample period: the current reaching the spool and the RK4 step lengths, delay included.

    Without a fractional delay a period is ``substeps`` equal steps. With one, the period
    is cut where the delayed output switches and gets ``substeps + 1`` steps shared
    between the two pieces (per run), so the switch falls on a step boundary.
    """

    def __init__(self, a: RigArrays, substeps: int, K: int) -> None:
        T, self.valve, self.cols = a.T, _Valve(a), np.arange(a.n)
        self.lag = np.floor(a.delay / T + 1e-9).astype(int)
        phase = a.delay - self.lag * T
        phase[phase < 1e-9 * T] = 0.0
        self.L = int(self.lag.max()) + 1
        self.hist = np.zeros((K + self.L, a.n))  # hist[k + L] = u_k; earlier rows: output before the start
        self.split = bool(phase.any())
        self.n_steps = substeps + 1 if self.split else substeps
        self.h = T / substeps
        if self.split:
            self.n_a = np.clip(np.round(phase / T * self.n_steps), 1, substeps)
            self.h_a, self.h_b = phase / self.n_a, (T - phase) / (self.n_steps - self.n_a)

    def record(self, k: int, u: Array) -> None:
        self.hist[k + self.L] = u

    def steps(self, k: int) -> list[tuple[Array, float | Array]]:
        """(i_cmd [mA], h [s]) for each RK4 step of period k."""
        held = self.hist[k + self.L - self.lag, self.cols]
        if not self.split:
            return [(self.valve(held), self.h)] * self.n_steps
        i_a = self.valve(self.hist[k + self.L - self.lag - 1, self.cols])
        i_b = self.valve(held)
        return [
            (np.where(j < self.n_a, i_a, i_b), np.where(j < self.n_a, self.h_a, self.h_b)) for j in range(self.n_steps)
        ]


def _loop(a: RigArrays, r_k: Array, noise: Array | None, substeps: int) -> tuple[Array, Array]:
    """Run the digital loop over the sample grid (``r_k`` of shape (K,) or (K, n));
    returns (y_k, u_k), each of shape (K, n)."""
    K, n = r_k.shape[0], a.n
    spool = bool(a.spool.any())
    reset_spool = spool and not a.spool.all()  # runs without spool lag follow i_cmd directly
    st = np.zeros((SD + 1 if spool else P + 1, n))
    st[X] = r_k[0]
    stuck = a.Fc > 0
    integ, e_prev = np.zeros(n), np.zeros(n)
    Y = np.empty((K, n))
    sched, rk4 = _Schedule(a, substeps, K), _Integrator(a, st.shape[0])
    for k in range(K):
        y = _measure(a, st[X], None if noise is None else noise[k])
        e = a.k_fb * (r_k[k] - y)
        integ += e
        sched.record(k, np.clip(a.Kp * e + a.Ki_T * integ + a.Kd_T * (e - e_prev), -DAC_LIMIT, DAC_LIMIT))
        Y[k], e_prev = y, e
        for i_cmd, h in sched.steps(k):
            if reset_spool:
                st[S] = np.where(a.spool > 0, st[S], i_cmd)
            st = rk4.step(st, stuck, i_cmd, h)
    return Y, sched.hist[sched.L:]


def _grid(t: Array, r: Array, T: float) -> tuple[Array, Array]:
    """Controller instants from t[0] and the command held at each (as in grader.model.sampled):
    shape (K,) for a shared command, (K, n) for one per run."""
    n = int(np.floor((t[-1] - t[0]) / T + 1e-9)) + 1
    grid = t[0] + T * np.arange(n)
    idx = np.clip(np.searchsorted(t, grid + 1e-12 * T, side="right") - 1, 0, len(t) - 1)
    return grid, (r[idx] if r.ndim == 1 else r[:, idx].T.copy())


def _check_inputs(t: Array, r: Array) -> None:
    if t.ndim != 1 or t.size < 2 or r.ndim not in (1, 2) or r.shape[-1] != t.size:
        raise SimulationError(
            f"t must be 1-D (>= 2 samples) and r of shape (len(t),) or (n, len(t)); got {t.shape} and {r.shape}"
        )
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(r))):
        raise SimulationError("t and r must be finite")
    if np.any(np.diff(t) <= 0):
        raise SimulationError("t must be strictly increasing")


def simulate_rig_batch(
    params: RigParams | Sequence[RigParams],
    controller: Controller | Sequence[Controller],
    t: Array,
    r: Array,
    effects: EffectSet | Sequence[EffectSet] = NO_EFFECTS,
    *,
    rng: np.random.Generator | None = None,
    substeps: int | None = None,
) -> tuple[Array, Array]:
    """Simulate n runs at once: (y [in], u [V]), each of shape (n, len(t)).

    ``r`` [in] is one command for all runs (shape (len(t),)) or one per run (n, len(t)).
    Each of ``params``, ``controller``, ``effects`` is one object shared by the batch or a
    sequence of n. Sensor noise is drawn from ``rng`` (default: seed 0). ``substeps`` per
    sample defaults to :meth:`RigArrays.substeps`. All runs must share ``sample_time``.
    """
    t, r = np.asarray(t, dtype=float), np.asarray(r, dtype=float)
    _check_inputs(t, r)
    a = resolve(params, controller, effects, n=r.shape[0] if r.ndim == 2 else 1)
    if r.ndim == 2 and r.shape[0] != a.n:
        raise SimulationError(f"batch: {r.shape[0]} commands for a batch of {a.n} runs (give 1 or {a.n})")
    grid, r_k = _grid(t, r, a.T)
    noise = None
    if a.sigma.any():
        noise = (rng or np.random.default_rng(0)).standard_normal((grid.size, a.n)) * a.sigma
    n_sub = substeps or a.substeps()
    if n_sub < 1:
        raise SimulationError(f"substeps must be >= 1, got {n_sub}")
    Y, U = _loop(a, r_k, noise, n_sub)
    if grid.size == t.size and np.allclose(grid, t, rtol=0, atol=1e-9 * a.T):
        return Y.T.copy(), U.T.copy()
    y = np.array([np.interp(t, grid, col) for col in Y.T])
    u = U.T[:, np.clip(np.searchsorted(grid, t + 1e-12 * a.T, side="right") - 1, 0, grid.size - 1)]
    return y, u


def simulate_rig(
    params: RigParams,
    controller: Controller,
    t: Array,
    r: Array,
    effects: EffectSet = NO_EFFECTS,
    *,
    rng: np.random.Generator | None = None,
    substeps: int | None = None,
) -> tuple[Array, Array]:
    """One run: (y [in] as the pot/ADC reports it, u [V] the controller output) on ``t``."""
    y, u = simulate_rig_batch(params, controller, t, r, effects, rng=rng, substeps=substeps)
    return y[0], u[0]
