"""An identified value with its unit, 95 % interval, method and inputs; and the
delta-method propagation used to carry uncertainty from measurements to results."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import stats

Z95 = float(stats.norm.ppf(0.975))


@dataclass(frozen=True)
class Estimate:
    """``value`` [unit] with standard error ``se`` and 95 % ``interval``."""

    value: float
    unit: str
    se: float
    method: str
    inputs: Mapping[str, float | str] = field(default_factory=dict)
    dof: float = np.inf

    @property
    def interval(self) -> tuple[float, float]:
        k = Z95 if not np.isfinite(self.dof) else float(stats.t.ppf(0.975, self.dof))
        return (self.value - k * self.se, self.value + k * self.se)


def propagate(
    f: Callable[[Mapping[str, float]], Sequence[float]],
    x: Mapping[str, float],
    se: Mapping[str, float],
    *,
    rel_step: float = 1e-4,
) -> tuple[np.ndarray, np.ndarray]:
    """Delta method for independent inputs: (f(x), standard errors of each output).

    ``f`` maps named inputs to a vector of outputs; central differences with a step of
    ``rel_step`` times each input's magnitude (or its se if smaller).
    """
    y0 = np.asarray(f(x), dtype=float)
    var = np.zeros_like(y0)
    for name, s in se.items():
        if s <= 0:
            continue
        h = min(abs(x[name]) * rel_step or rel_step, s)
        up = np.asarray(f({**x, name: x[name] + h}), dtype=float)
        dn = np.asarray(f({**x, name: x[name] - h}), dtype=float)
        var += ((up - dn) / (2 * h) * s) ** 2
    return y0, np.sqrt(var)
