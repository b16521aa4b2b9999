"""The precision at which grader writes numbers: :data:`SIGNIFICANT_DIGITS` significant digits.

Floating-point results differ in their last digits from CPU to CPU (BLAS kernels, fused
multiply-add); written at 6 significant digits — a relative step of 1e-6, far above that
noise (~1e-12) and far below any grading tolerance (≥ 0.1 %) — every key, grade output and
diagnosis is the same bytes on every machine. Values of one group (a complex pole) share
one grid, that of the group's largest magnitude, so the real part of a pole on the
imaginary axis is written as 0.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

SIGNIFICANT_DIGITS = 6


def round_sig(x: float, digits: int = SIGNIFICANT_DIGITS) -> float:
    """``x`` rounded to ``digits`` significant digits (non-finite values unchanged, -0.0 → 0.0)."""
    if not math.isfinite(x) or x == 0:
        return x + 0.0
    return float(f"{x:.{digits}g}") + 0.0


def round_group(values: Sequence[float], digits: int = SIGNIFICANT_DIGITS) -> list[float]:
    """Round values that belong together (a complex pole's real and imaginary parts) on one
    absolute grid: ``digits`` significant digits of the group's largest magnitude, so a
    numerical zero (e.g. ``-3.6e-15`` beside ``157.8``) is written as 0."""
    scale = max((abs(v) for v in values if math.isfinite(v)), default=0.0)
    if scale == 0:
        return [v + 0.0 for v in values]
    exponent = math.floor(math.log10(scale)) - digits + 1
    return [float(f"{round(v / 10.0**exponent)}e{exponent}") + 0.0 if math.isfinite(v) else v for v in values]


def rounded(obj: Any, digits: int = SIGNIFICANT_DIGITS) -> Any:
    """A copy of a JSON-like tree with every float rounded by :func:`round_sig`."""
    if isinstance(obj, bool) or obj is None or isinstance(obj, (int, str)):
        return obj
    if isinstance(obj, float):
        return round_sig(obj, digits)
    if isinstance(obj, Mapping):
        return {k: rounded(v, digits) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [rounded(v, digits) for v in obj]
    return obj
