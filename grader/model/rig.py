"""The nonlinear rig simulator: the real closed loop, unmodelled effects included.

Signal path at every sample instant t_k = k·T (the rig's digital loop)::

    pot -> [sensor_noise] -> [sensor_quantization, ADC ±10 V] -> y_k (recorded and fed back)
    e_k = k_fb·(r_k − y_k);  u_k = Kp e_k + Ki T Σ e_j + Kd (e_k − e_{k−1})/T, clipped to the DAC's ±10 V
    u_k held (ZOH) [+ sampling_delay] -> amplifier i = Kamp·u, clipped to ±i_max of RigParams
      -> [valve_saturation] -> [valve_hysteresis] -> [valve_dynamics] -> [valve_deadband]
      -> flow QL = Kq·i_s [·orifice law: pressure_flow_nonlinearity] − Kce·PL

Plant (:mod:`grader.model.hydraulic`): dPL/dt = g·(QL − A·v), M·dv/dt = A·PL − B·v − friction,
dx/dt = v; ``coulomb_friction`` is stick-slip: a mass at rest stays at rest while |A·PL| <= Fc.
With no effect on, this is exactly the linear model of :mod:`grader.model.sampled` (same law,
instants, ZOH, start at rest at y = r[0]). The compiled engine (:mod:`grader.model.engine`)
steps the plant exactly (zero-order hold) where it is linear and with RK4 substeps where it
is not, and locates stick-slip events inside the step. The recorded u is the controller
output at its sample instant (before any delay).

API::

    y, u = simulate_rig(params, controller, t, r, effects, rng=rng)          # one run: y [in], u [V]
    Y, U = simulate_rig_batch(params_list, controller, t, r, effects_list)   # shape (n, len(t))
    xs = simulate_positions(params_list, controllers, effects_list, commands, noise)  # x_k of sampled runs
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from grader.errors import SimulationError
from grader.model.effects import NO_EFFECTS, EffectSet
from grader.model.params import Controller, RigParams
from grader.model.rig_setup import RigArrays, resolve

Array = NDArray[np.float64]
#: Most RK4 substeps per sample: a model beyond it (a fitter's trial at absurd β/Vt or Kce) would take hours.
MAX_SUBSTEPS = 2000


def _engine_run(a: RigArrays, r_k: Array, noise: Array, K: NDArray[np.int64], substeps: int | None, *,
                too_fast: str = "raise", max_substeps: int = MAX_SUBSTEPS, replay: bool = False
                ) -> tuple[Array, Array, Array]:
    """The compiled engine on padded per-run rows (imported here: numba loads on first use). A run whose
    cost grows with its fastest mode (:func:`grader.model.engine.stepped`) and whose fastest mode needs more than
    ``max_substeps`` per sample is an error (``too_fast="raise"``) or, for a fitter's trial model (``"nan"``),
    not simulated: its rows are NaN. A linear run without events takes one exact step per sample at any
    stiffness. With ``replay``, ``noise`` holds each run's recorded controller output [V], which drives it."""
    from grader.model import engine

    m = a.substeps() if substeps is None else np.full(a.n, substeps, dtype=np.int64)
    if substeps is not None and substeps < 1:
        raise SimulationError(f"substeps must be >= 1, got {substeps}")
    fast = (m > max_substeps) & engine.stepped(a)
    if fast.any() and too_fast == "raise":
        j = int(np.flatnonzero(fast)[0])
        raise SimulationError(f"run {j}: the rig's fastest mode needs {int(m[j])} substeps per sample (more than "
                              f"{MAX_SUBSTEPS}); check its beta_over_Vt, Kce and the spool's tau")
    with np.errstate(all="ignore"):  # a wildly unstable trial model may overflow: its output says so
        Y, U, X = engine.run(a, r_k, noise, np.where(fast, 0, K), np.where(fast, 1, m), np.full(a.n, replay))
    Y[fast], U[fast], X[fast] = np.nan, np.nan, np.nan
    return Y, U, X


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
    sequence of n. Sensor noise is drawn from ``rng`` (default: seed 0). ``substeps``: RK4
    steps per sample where the plant is not linear between events (elsewhere each hold interval
    is one exact step); default :meth:`RigArrays.substeps` of each run. All runs must share ``sample_time``.
    """
    t, r = np.asarray(t, dtype=float), np.asarray(r, dtype=float)
    _check_inputs(t, r)
    a = resolve(params, controller, effects, n=r.shape[0] if r.ndim == 2 else 1)
    if r.ndim == 2 and r.shape[0] != a.n:
        raise SimulationError(f"batch: {r.shape[0]} commands for a batch of {a.n} runs (give 1 or {a.n})")
    grid, r_k = _grid(t, r, a.T)
    noise = np.zeros((grid.size, a.n))
    if a.sigma.any():
        noise = (rng or np.random.default_rng(0)).standard_normal((grid.size, a.n)) * a.sigma
    r_rows = np.broadcast_to(r_k.T if r_k.ndim == 2 else r_k, (a.n, grid.size))
    Y, U, _ = _engine_run(a, r_rows, noise.T, np.full(a.n, grid.size, dtype=np.int64), substeps)
    if grid.size == t.size and np.allclose(grid, t, rtol=0, atol=1e-9 * a.T):
        return Y, U
    y = np.array([np.interp(t, grid, row) for row in Y])
    u = U[:, np.clip(np.searchsorted(grid, t + 1e-12 * a.T, side="right") - 1, 0, grid.size - 1)]
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


@dataclass(frozen=True)
class PositionBatch:
    """Resolved runs of different lengths (picklable: another process can run it)."""

    a: RigArrays
    r: Array  # (n, Kmax) commands [in], padded with their last value
    noise: Array  # (n, Kmax) reading noise [in], or with replay the recorded controller output [V]
    K: NDArray[np.int64]  # samples of each run
    max_substeps: int = MAX_SUBSTEPS  # a run needing more RK4 substeps per sample is NaN
    replay: bool = False  # the recorded controller output drives each run (no controller)

    def run(self) -> list[Array]:
        """Position x_k [in] of each run, on its own samples."""
        _, _, X = _engine_run(self.a, self.r, self.noise, self.K, None, too_fast="nan", max_substeps=self.max_substeps,
                              replay=self.replay)
        return [X[j, :k].copy() for j, k in enumerate(self.K)]


def position_batch(params: Sequence[RigParams], controllers: Sequence[Controller], effects: Sequence[EffectSet],
                   commands: Sequence[Array], noise: Sequence[Array] | None = None, *,
                   max_substeps: int = MAX_SUBSTEPS, replay: bool = False) -> PositionBatch:
    """Runs (params[j], controllers[j], effects[j]) for sampled commands ``commands[j]`` [in] (lengths
    may differ) whose controller reads x_k + ``noise[j][k]`` [in] (default 0); a run whose fastest mode
    needs more than ``max_substeps`` RK4 substeps per sample comes back NaN. With ``replay``, ``noise[j]`` is
    instead the controller output [V] a rig recorded, and it drives the run in place of the controller."""
    a = resolve(params, controllers, effects, n=len(commands))
    K = np.array([c.size for c in commands], dtype=np.int64)
    r, nz = np.zeros((a.n, int(K.max()))), np.zeros((a.n, int(K.max())))
    for j, c in enumerate(commands):
        r[j, :c.size], r[j, c.size:] = c, c[-1]
        if noise is not None:
            nz[j, :c.size] = noise[j]
    return PositionBatch(a, r, nz, K, max_substeps, replay)


def simulate_positions(params: Sequence[RigParams], controllers: Sequence[Controller], effects: Sequence[EffectSet],
                       commands: Sequence[Array], noise: Sequence[Array] | None = None) -> list[Array]:
    """Position x_k [in] of each run of :func:`position_batch`, on its own samples."""
    return position_batch(params, controllers, effects, commands, noise).run()
