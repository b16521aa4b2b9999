"""Candidate explanations of the gap: each canonical effect, plus ``none``.

A candidate's parameter vector is ``θ = [ln(β/Vt ÷ β/Vt₀), ln(Kce ÷ Kce₀), ln(Kq ÷ Kq₀), m₁ …]``
(where the runs' rests hold the valve's null against friction, :func:`grader.gap.null.free`, the null current
leads the magnitudes as one more coordinate, ``i0 ÷ null_scale``, fitted with every candidate):
the linear model's β/Vt and Kce are always re-fitted (an unmodelled effect biases them), and
so is the loop gain through Kq (the flow test that gives Kq sees the valve's own effects, and
near the critical gain a loop gain off by 0.1 % changes the instability run's growth visibly).
Each effect magnitude m is the parameter's value divided by the top of its realistic range
(from :mod:`grader.model.effects`), so every coordinate is O(1).
``sensor_noise`` and ``sensor_quantization`` are measurement noise, not candidates
(see :mod:`grader.gap.noise`); ``valve_dynamics`` is fitted as a first-order spool lag, and as a second-order
spool where the verdict is a delay or that lag, or a delay or the lag on top is a verdict's best addition
(:mod:`grader.gap.spool`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from grader.gap.backend import Point
from grader.model.effects import EFFECTS, EffectSet, ParamSpec
from grader.model.params import RigParams

Array = NDArray[np.float64]
NONE = "none"
SATURATION = "valve_saturation"
LEAST_LIMIT = EFFECTS[SATURATION].param("i_max").lo  # [mA], the least current limit of the realistic range
#: Canonical effects that describe the sensor, not the physics: part of the noise floor.
NOISE_EFFECTS = ("sensor_noise", "sensor_quantization")
#: Not fitted to the runs unless asked for: with the loop gain free, viscous friction is exactly a larger Kce
#: (:mod:`grader.gap.evidence` names it from the friction test or the flow test's loop gain instead).
NOT_FROM_RUNS = ("viscous_friction",)
#: Parameters held fixed when fitting (effect -> {param: value}).
FIXED: Mapping[str, Mapping[str, float]] = {"valve_dynamics": {"order": 1.0, "zeta": 0.7}}
#: Forward-difference steps (log ratios, magnitudes): small where the model is smooth in θ, larger for
#: the switching effects (stick-slip, backlash, deadband, a current limit), whose residual has kinks.
SMOOTH_STEPS, SWITCHING_STEPS = (1e-4, 1e-3), (2e-3, 2e-2)
SWITCHING = frozenset({"coulomb_friction", "valve_hysteresis", "valve_deadband", "valve_saturation"})
GRID_POINTS = 5
#: :meth:`Candidate.strength` below which an effect barely acts: named neither as a second effect
#: (:mod:`grader.gap.pairs`) nor let stand for ``none`` at a worse optimum (:mod:`grader.gap.search`).
WEAK_STRENGTH = 0.06
#: The linear model's parameters re-fitted with every candidate (log ratios lead θ), with their units.
LINEAR: tuple[tuple[str, str], ...] = (("beta_over_Vt", "psi/in**3"), ("Kce", "in**3/s/psi"), ("Kq", "in**3/s/mA"))
N_LINEAR = len(LINEAR)
#: Most β/Vt [psi/in³] a fit tries: twenty times the top of the realistic rig space (docs/reference/rig-space.md),
#: as far as the span lets a fit around a realistic baseline go. Where the runs cannot pin β/Vt (no oscillation to
#: read), fits ran up to 270 times the top: such a model is no rig, and its stiffness cost 200-800 RK4 substeps per
#: sample (40 s for a diagnosis).
LINEAR_CEILING = {"beta_over_Vt": 1.6e6}
#: How far (log ratio) a linear parameter may move from the baseline's: a factor 20.
LINEAR_SPAN = 3.0
#: How far a fitted null may move from the one held in the runs, in units of :attr:`Candidate.null_scale`.
NULL_SPAN = 2.0


@dataclass(frozen=True)
class FitParam:
    """A fitted parameter of ``effect``: value = m·scale, with bounds lo ≤ value ≤ hi [unit]."""

    effect: str
    name: str
    unit: str
    scale: float
    lo: float
    hi: float
    typical_lo: float

    def grid(self, n: int = GRID_POINTS) -> Array:
        """Starting magnitudes m, log-spaced over the realistic range (from 1/16 of its top, and 0,
        if it starts at 0); for a current limit, the share of the demand it cuts off is log-spaced (from
        5 %: a limit at the demand does nothing, and a fit started there cannot move)."""
        if self.name == "i_max":
            return 1.0 - np.geomspace(LIMIT_CUT, 1.0 - self.typical_lo / self.scale, n)
        if self.typical_lo > 0:
            return np.geomspace(self.typical_lo / self.scale, 1.0, n)
        return np.concatenate([[0.0], np.geomspace(1.0 / 16.0, 1.0, n - 1)])

    @property
    def neutral(self) -> float:
        """The magnitude m at which the effect does nothing, or as little as it can: a current limit at the
        amplifier's, any other parameter at its least fitted value (0; a spool lag at :data:`FIT_FLOOR`, whose phase
        the instability run still feels at the margin of stability)."""
        return (self.hi if self.name == "i_max" else self.lo) / self.scale


#: A current limit is searched from this share of the largest current the runs ask for up to that current,
#: starting from limits that cut off at least LIMIT_CUT of it.
DEMAND_SHARE, LIMIT_CUT = 0.05, 0.05


#: Least fitted value, as a share of the realistic range's top: a spool lag of 0.1 ms (1.6 kHz) acts as no lag in a
#: loop sampled at 0.5 ms or slower, while a faster spool mode makes every stick-slip event costly to locate.
FIT_FLOOR = {"tau": 0.02}


def _fit_param(effect: str, spec: ParamSpec, upper: float | None = None, demand: float | None = None) -> FitParam:
    hi = spec.hi if upper is None else min(spec.hi, upper)
    if spec.name == "i_max" and demand is not None and demand > 0:
        top = min(demand, hi)  # a limit above every current the runs ask for does nothing
        return FitParam(effect, spec.name, spec.unit, top, spec.lo, hi, max(spec.lo, DEMAND_SHARE * top))
    lo = max(spec.lo, FIT_FLOOR.get(spec.name, 0.0) * spec.typical[1])
    return FitParam(effect, spec.name, spec.unit, spec.typical[1], lo, hi, spec.typical[0])


@dataclass(frozen=True)
class Candidate:
    """An effect (or ``none``, or effects added greedily, ``a+b``) with its fitted parameters."""

    effect: str
    params: tuple[FitParam, ...] = ()
    fixed: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    names: tuple[str, ...] = ()
    #: [mA] the unit of the valve's null current, fitted as θ's coordinate :data:`N_LINEAR` (0: not fitted; the
    #: null, if any, is the one held in the runs)
    null_scale: float = 0.0

    @property
    def lead(self) -> int:
        """Coordinates of θ before the effects' magnitudes: the linear ones, and the null's where it is fitted."""
        return N_LINEAR + (self.null_scale > 0.0)

    @property
    def n_theta(self) -> int:
        return self.lead + len(self.params)

    def null_current(self, theta: Array) -> float:
        """The fitted null current [mA] at θ: where the valve passes no flow, beyond the null held in the runs (0
        where it is not fitted)."""
        return float(theta[N_LINEAR]) * self.null_scale if self.null_scale > 0.0 else 0.0

    def held(self) -> dict[str, tuple[float, str]]:
        """The held parameters (value, unit) of an effect fitted in a form other than its default (a second-order
        spool's order and damping), by report key (see :meth:`label`); empty for the default forms."""
        out: dict[str, tuple[float, str]] = {}
        for name, fixed in self.fixed.items():
            spec = EFFECTS[name]
            if any(v != spec.param(p).default for p, v in fixed.items()):
                out.update({p if len(self.names) < 2 else f"{name}.{p}": (v, spec.param(p).unit)
                            for p, v in fixed.items()})
        return out

    def label(self, p: FitParam) -> str:
        """A parameter's key in reports: its name, prefixed by its effect in a combination."""
        return p.name if len(self.names) < 2 else f"{p.effect}.{p.name}"

    def steps(self) -> Array:
        """Forward-difference step per coordinate of θ."""
        log_step, mag_step = SWITCHING_STEPS if SWITCHING & set(self.names) else SMOOTH_STEPS
        return np.array([log_step] * N_LINEAR + [mag_step] * (self.n_theta - N_LINEAR))

    def bounds(self, base: RigParams | None = None) -> tuple[Array, Array]:
        """(lower, upper) of θ; the log ratios are kept within :data:`LINEAR_SPAN`, and around ``base`` also below
        :data:`LINEAR_CEILING` (never below the baseline's own value)."""
        top = [LINEAR_SPAN if base is None or name not in LINEAR_CEILING else
               float(np.clip(np.log(LINEAR_CEILING[name] / getattr(base, name)), 0.0, LINEAR_SPAN))
               for name, _ in LINEAR]
        null = [NULL_SPAN] * (self.lead - N_LINEAR)
        lo = [-LINEAR_SPAN] * N_LINEAR + [-x for x in null] + [p.lo / p.scale for p in self.params]
        hi = top + null + [p.hi / p.scale for p in self.params]
        return np.array(lo), np.array(hi)

    def values(self, theta: Array) -> dict[str, dict[str, float]]:
        """{effect: {parameter: value [internal units]}} at θ, held parameters included."""
        out: dict[str, dict[str, float]] = {n: dict(self.fixed.get(n, {})) for n in self.names}
        for p, m in zip(self.params, theta[self.lead:]):
            out[p.effect][p.name] = float(np.clip(m * p.scale, p.lo, p.hi))
        return out

    def strength(self, theta: Array) -> float:
        """How strongly the (last added) effect acts at θ, as a fraction of its realistic range's top
        (saturation: the share of the largest current the runs ask for that it cuts off; no parameters,
        as the orifice law: 1)."""
        if not self.names:
            return 0.0
        own = [(j, p) for j, p in enumerate(self.params, start=self.lead) if p.effect == self.names[-1]]
        if not own:
            return 1.0
        j, p = own[0]
        if p.name == "i_max":
            return max(0.0, 1.0 - float(theta[j]))
        return float(theta[j])

    def nesting(self, reference: Array) -> Array:
        """θ of this candidate that acts as the one it extends does at ``reference`` (that one's θ, a prefix):
        the magnitudes added on top at their neutral values (:attr:`FitParam.neutral`). Exactly so, except for a
        spool lag (nearly: its least fitted time constant) and the orifice law (no parameter: it stays on)."""
        assert self.lead <= reference.size <= self.n_theta, "the reference must be a prefix of this θ"
        extra = self.params[reference.size - self.lead:]
        return np.concatenate([reference, [p.neutral for p in extra]])

    def with_null(self, scale: float, theta: Array) -> tuple[Candidate, Array]:
        """This candidate with the valve's null fitted in units of ``scale`` [mA], and ``theta`` as its θ (the
        null at 0: the same model)."""
        assert self.null_scale == 0.0, "the null is fitted already"
        return replace(self, null_scale=scale), np.insert(theta, N_LINEAR, 0.0)

    def point(self, base: RigParams, theta: Array) -> Point:
        """The model at θ around the baseline ``base`` (a fitted null as the controller output's shift,
        −i0/Kamp [V])."""
        p = base.with_(**{name: float(getattr(base, name) * np.exp(theta[j])) for j, (name, _) in enumerate(LINEAR)})
        return Point(p, EffectSet(self.values(theta)), -self.null_current(theta) / base.Kamp)


def combine(first: Candidate, second: Candidate) -> Candidate:
    """``second`` added on top of ``first`` (θ: first's, then second's magnitudes; the null as first's)."""
    return Candidate(f"{first.effect}+{second.effect}", first.params + second.params,
                     {**first.fixed, **second.fixed}, first.names + second.names, first.null_scale)


def split_last(c: Candidate) -> tuple[Candidate, Candidate]:
    """``c`` = :func:`combine` (head, last) taken apart again: (head, last), each with its own parameters and held
    values, the null with head (a single effect's head is ``none``)."""
    name = c.names[-1]
    own = tuple(p for p in c.params if p.effect == name)
    head = Candidate(c.effect.rsplit("+", 1)[0] if len(c.names) > 1 else NONE, c.params[:len(c.params) - len(own)],
                     {k: v for k, v in c.fixed.items() if k != name}, c.names[:-1], c.null_scale)
    return head, Candidate(name, own, {k: v for k, v in c.fixed.items() if k == name}, (name,))


def make_candidates(base: RigParams, names: Sequence[str] | None = None, *, demand: float | None = None) -> list[Candidate]:
    """``none`` and every physical canonical effect but :data:`NOT_FROM_RUNS` (or only ``names``), in canonical
    order; ``demand`` [mA], the largest valve current the runs ask for, sets the range a current limit is
    searched over."""
    wanted = [n for n in physical_effects() if n not in NOT_FROM_RUNS] if names is None else list(names)
    out = [Candidate(NONE)]
    for name in wanted:
        if name == NONE or (name == SATURATION and not saturation_can_act(demand)):
            continue
        spec = EFFECTS[name]
        fixed = FIXED.get(name, {})
        upper = {"i_max": base.i_max}
        params = tuple(_fit_param(name, p, upper.get(p.name), demand) for p in spec.params if p.name not in fixed)
        out.append(Candidate(name, params, {name: fixed} if fixed else {}, (name,)))
    return out


def saturation_can_act(demand: float | None) -> bool:
    """Whether a current limit within its realistic range can cut the runs' largest current ``demand`` [mA]
    (None: not known, assumed so): a limit at its least value, :data:`LEAST_LIMIT`, or above clips nothing smaller."""
    return demand is None or demand > LEAST_LIMIT


def physical_effects() -> tuple[str, ...]:
    """Canonical effects that can be candidates."""
    return tuple(n for n in EFFECTS if n not in NOISE_EFFECTS)
