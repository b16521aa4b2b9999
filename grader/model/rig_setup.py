"""Flatten a batch of (RigParams, Controller, EffectSet) into per-run arrays for the rig integrator.

An effect that is off takes its neutral value (Fc = 0, no saturation, zero widths,
no delay, no spool lag, no quantisation, no noise), so runs with different effect
sets share one batch. All arrays have shape ``(n,)`` in internal units.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TypeVar

import numpy as np
from numpy.typing import NDArray

from grader.errors import SimulationError
from grader.model.effects import EffectSet
from grader.model.params import Controller, RigParams

Array = NDArray[np.float64]
T_ = TypeVar("T_")

#: DAC output limit of the data-acquisition board [V]; the ADC spans the same ±10 V.
DAC_LIMIT = 10.0
ADC_SPAN = 2 * DAC_LIMIT
#: Largest substep relative to the fastest time scale (|lambda|·h).
STEP_FACTOR = 0.5


@dataclass(frozen=True)
class RigArrays:
    """Per-run parameters: plant, controller, effects (neutral values when off)."""

    T: float
    A: Array
    inv_M: Array
    g: Array  # 4·beta/Vt [psi/in³]
    Kq: Array
    Kce: Array
    B: Array  # linear-model B plus viscous_friction:B
    Kamp: Array
    i_lim: Array  # min(amplifier limit, valve_saturation:i_max) [mA]
    k_fb: Array
    Kpot: Array
    Kp: Array
    Ki_T: Array  # Ki·T
    Kd_T: Array  # Kd/T
    Fc: Array
    half_hyst: Array
    half_db: Array
    inv_Ps: Array  # 1/Ps with the orifice law, else 0
    delay: Array
    spool: Array  # 1.0 where the spool has dynamics
    c0: Array  # order 1: 1/tau
    order2: Array  # 1.0 where the spool is second order
    w2: Array  # order 2: 1/tau²
    z2: Array  # order 2: 2·zeta/tau
    lsb: Array  # ADC step [V], 0 = no quantisation
    counts_per_in: Array  # ADC counts per inch of travel (1 where there is no quantisation)
    quantised: bool
    sigma: Array

    @property
    def n(self) -> int:
        return self.A.size

    def substeps(self) -> NDArray[np.int64]:
        """Substeps per sample period of each run, so that |lambda|·h <= STEP_FACTOR for its fastest mode."""
        a2 = self.B * self.inv_M + self.g * self.Kce
        a1 = self.g * self.A**2 * self.inv_M
        fastest = np.maximum.reduce([np.sqrt(a1), a2, self.c0, np.sqrt(self.w2) + self.z2])
        return np.maximum(2, np.ceil(self.T * fastest / STEP_FACTOR)).astype(np.int64)


def _as_list(value: T_ | Sequence[T_], kind: type) -> list[T_]:
    return [value] if isinstance(value, kind) else list(value)  # type: ignore[arg-type, list-item]


def _broadcast(items: list[T_], n: int, what: str) -> list[T_]:
    if len(items) == n:
        return items
    if len(items) == 1:
        return items * n
    raise SimulationError(f"batch: {len(items)} {what} for a batch of {n} runs (give 1 or {n}; commands count too)")


def _effect(effects: list[EffectSet], name: str, param: str, off: float) -> Array:
    return np.array([e.value(name, param) if name in e else off for e in effects])


def _spool(effects: list[EffectSet]) -> tuple[Array, Array, Array, Array]:
    tau = _effect(effects, "valve_dynamics", "tau", 0.0)
    order = _effect(effects, "valve_dynamics", "order", 1.0)
    zeta = _effect(effects, "valve_dynamics", "zeta", 0.7)
    on = tau > 0
    inv = np.divide(1.0, tau, out=np.zeros_like(tau), where=on)
    first, second = on & (order == 1), on & (order == 2)
    return on.astype(float), inv * first, inv**2 * second, 2 * zeta * inv * second


def resolve(
    params: RigParams | Sequence[RigParams],
    controller: Controller | Sequence[Controller],
    effects: EffectSet | Sequence[EffectSet],
    *,
    n: int = 1,
) -> RigArrays:
    """Arrays for a batch of at least ``n`` runs; each argument is one object (shared) or a sequence of n."""
    ps, cs, es = _as_list(params, RigParams), _as_list(controller, Controller), _as_list(effects, EffectSet)
    n = max(len(ps), len(cs), len(es), n)
    if min(len(ps), len(cs), len(es)) == 0:
        raise SimulationError("batch: empty parameter, controller or effect list")
    ps, cs, es = _broadcast(ps, n, "parameter sets"), _broadcast(cs, n, "controllers"), _broadcast(es, n, "effect sets")
    T = ps[0].sample_time
    if T <= 0 or any(p.sample_time != T for p in ps):
        raise SimulationError("batch: every run needs the same positive sample_time")

    def col(get: object) -> Array:
        return np.array([get(p) for p in ps], dtype=np.float64)  # type: ignore[operator]

    if any(p.supply_pressure <= 0 for p, e in zip(ps, es) if "pressure_flow_nonlinearity" in e):
        raise SimulationError("pressure_flow_nonlinearity needs a positive supply_pressure")
    spool, c0, w2, z2 = _spool(es)
    bits = _effect(es, "sensor_quantization", "bits", 0.0)
    i_sat = _effect(es, "valve_saturation", "i_max", math.inf)
    lsb = np.where(bits > 0, ADC_SPAN / 2.0 ** np.maximum(bits, 1), 0.0)
    return RigArrays(
        T=T, A=col(lambda p: p.A), inv_M=col(lambda p: 1.0 / p.M), g=col(lambda p: 4.0 * p.beta_over_Vt),
        Kq=col(lambda p: p.Kq), Kce=col(lambda p: p.Kce),
        B=col(lambda p: p.B) + _effect(es, "viscous_friction", "B", 0.0),
        Kamp=col(lambda p: p.Kamp), i_lim=np.minimum(col(lambda p: p.i_max), i_sat),
        k_fb=col(lambda p: p.k_fb), Kpot=col(lambda p: p.Kpot),
        Kp=np.array([c.Kp for c in cs]), Ki_T=np.array([c.Ki * T for c in cs]), Kd_T=np.array([c.Kd / T for c in cs]),
        Fc=_effect(es, "coulomb_friction", "Fc", 0.0),
        half_hyst=_effect(es, "valve_hysteresis", "width", 0.0) / 2,
        half_db=_effect(es, "valve_deadband", "width", 0.0) / 2,
        inv_Ps=np.array([1.0 / p.supply_pressure if "pressure_flow_nonlinearity" in e else 0.0 for p, e in zip(ps, es)]),
        delay=_effect(es, "sampling_delay", "delay", 0.0),
        spool=spool, c0=c0, order2=(w2 > 0).astype(float), w2=w2, z2=z2,
        lsb=lsb, counts_per_in=np.where(lsb > 0, col(lambda p: p.Kpot) / np.where(lsb > 0, lsb, 1.0), 1.0),
        quantised=bool(lsb.any()),
        sigma=_effect(es, "sensor_noise", "sigma", 0.0),
    )
