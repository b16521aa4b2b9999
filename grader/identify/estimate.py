"""An identified value with its unit, 95 % interval, method and inputs; and the
delta-method propagation used to carry uncertainty from measurements to results.

An Estimate may be ``not_reachable`` (the identified rig has no such value: ``value`` is
NaN and ``reason`` says why), ``not_identifiable`` (the data cannot give it, e.g. an instability
run that does not oscillate: also NaN with a reason), or carry a ``note`` (e.g. clipped at a
physical bound).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from scipy import stats

Z95 = float(stats.norm.ppf(0.975))


@dataclass(frozen=True)
class Estimate:
    """``value`` [unit] with standard error ``se`` and 95 % ``interval``; ``status``
    ``not_reachable`` (the rig has no such value) or ``not_identifiable`` (the data cannot give
    it), with a ``reason``."""

    value: float
    unit: str
    se: float
    method: str
    inputs: Mapping[str, float | str] = field(default_factory=dict)
    dof: float = np.inf
    status: Literal["ok", "not_reachable", "not_identifiable"] = "ok"
    reason: str | None = None
    note: str | None = None
    fit_interval: tuple[float, float] | None = None

    @property
    def interval(self) -> tuple[float, float]:
        if self.fit_interval is not None:
            return self.fit_interval
        k = Z95 if not np.isfinite(self.dof) else float(stats.t.ppf(0.975, self.dof))
        return (self.value - k * self.se, self.value + k * self.se)

    def clipped_below(self, bound: float = 0.0) -> Estimate:
        """This estimate clipped at a physical lower ``bound``: value = bound, the fit's
        interval is kept and a note says so (unchanged when value ≥ bound)."""
        if self.value >= bound:
            return self
        note = f"fitted {self.value:.4g}, below the physical bound {bound:g}: clipped to it; the interval is the fit's"
        return Estimate(bound, self.unit, self.se, self.method, self.inputs, self.dof, note=note, fit_interval=self.interval)


def not_reachable(unit: str, method: str, reason: str, inputs: Mapping[str, float | str] | None = None) -> Estimate:
    """An Estimate for a value the identified rig does not have."""
    return Estimate(float("nan"), unit, float("nan"), method, dict(inputs or {}), status="not_reachable", reason=reason)


def not_identifiable(unit: str, method: str, reason: str) -> Estimate:
    """An Estimate the dataset cannot give (``reason`` says why)."""
    return Estimate(float("nan"), unit, float("nan"), method, {}, status="not_identifiable", reason=reason)


def propagate(
    f: Callable[[Mapping[str, float]], Sequence[float]],
    x: Mapping[str, float],
    se: Mapping[str, float],
    *,
    rel_step: float = 1e-4,
) -> tuple[np.ndarray, np.ndarray]:
    """Delta method for independent inputs: (f(x), standard errors of each output).

    ``f`` maps named inputs to a vector of outputs (NaN where an output does not exist);
    central differences with a step of ``rel_step`` times each input's magnitude (or its
    se if smaller), one-sided where a perturbed output does not exist.
    """
    y0 = np.asarray(f(x), dtype=float)
    var = np.zeros_like(y0)
    for name, s in se.items():
        if s <= 0:
            continue
        h = min(abs(x[name]) * rel_step or rel_step, s)
        up = np.asarray(f({**x, name: x[name] + h}), dtype=float)
        dn = np.asarray(f({**x, name: x[name] - h}), dtype=float)
        with np.errstate(invalid="ignore"):
            d = np.where(np.isfinite(up) & np.isfinite(dn), (up - dn) / (2 * h),
                         np.where(np.isfinite(up), (up - y0) / h, (y0 - dn) / h))
        var += np.nan_to_num(d * s) ** 2
    return y0, np.sqrt(var)
