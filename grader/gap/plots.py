"""The diagnosis plots, as PNG bytes (matplotlib Agg, no global pyplot state).

* One figure per run: measured vs the linear model vs the augmented model (the verdict's
  effect), and below it the residuals of both models with the run's segments shaded.
* The candidates ranked by held-out shrink.
"""

from __future__ import annotations

import io

import matplotlib

matplotlib.use("Agg")

import numpy as np
from matplotlib.figure import Figure
from numpy.typing import NDArray

from grader.gap.runs import GapRun
from grader.gap.schema import Diagnosis
from grader.gap.segments import Segment
from grader.gap.summary import effect_name

Array = NDArray[np.float64]
DPI = 130
SEGMENT_COLOURS = {"rise": "#e0ecf4", "overshoot": "#fde0dd", "settling": "#fff7bc", "steady_state": "#e5f5e0",
                   "tracking": "#efedf5", "oscillation": "#fee6ce"}
MEASURED, LINEAR, AUGMENTED = "#222222", "#d95f02", "#1b9e77"


def png(fig: Figure) -> bytes:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=DPI, bbox_inches="tight", metadata={"Software": None})
    return buffer.getvalue()


def run_figure(run: GapRun, segs: list[Segment], y_lin: Array, y_aug: Array, effect: str) -> bytes:
    """Measured vs linear vs augmented model, and their residuals over the shaded segments."""
    fig = Figure(figsize=(8.0, 5.2))
    top, bottom = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [3, 2]})
    t = run.t
    aug_label = f"with {effect_name(effect)}" if effect != "none" else "linear, re-fitted"
    top.plot(t, run.r, color="#999999", lw=1.0, ls="--", label="command")
    top.plot(t, run.y, color=MEASURED, lw=1.0, label="measured")
    top.plot(t, y_lin, color=LINEAR, lw=1.2, label="linear model")
    top.plot(t, y_aug, color=AUGMENTED, lw=1.2, ls=(0, (4, 2)), label=aug_label)
    top.set_ylabel("position [in]")
    c = run.controller
    gains = f"Kp = {c.Kp:g}" + (f", Ki = {c.Ki:g}" if c.Ki else "") + (f", Kd = {c.Kd:g}" if c.Kd else "")
    top.set_title(f"{run.name} ({run.kind}, {gains})", fontsize=10)
    top.legend(fontsize=8, loc="best")
    _limits(top, run, y_lin)
    _shade(bottom, t, segs)
    bottom.plot(t, 1e3 * (y_lin - run.y), color=LINEAR, lw=0.8, label="linear − measured")
    bottom.plot(t, 1e3 * (y_aug - run.y), color=AUGMENTED, lw=0.8, label=f"{aug_label} − measured")
    bottom.axhline(0.0, color="#999999", lw=0.6)
    bottom.set_ylabel("residual [mil = 0.001 in]")
    bottom.set_xlabel("time [s]")
    bottom.legend(fontsize=7, loc="upper right", framealpha=0.9)
    fig.tight_layout()
    return png(fig)


def _shade(ax: object, t: Array, segs: list[Segment]) -> None:
    """Shade the segments; label each above the panel, staggering labels of narrow neighbours."""
    span = float(t[-1] - t[0])
    last_end, level = -np.inf, 0
    for s in segs:
        if s.i1 <= s.i0:
            continue
        t0, t1 = float(t[s.i0]), float(t[s.i1 - 1])
        ax.axvspan(t0, t1, color=SEGMENT_COLOURS[s.name], lw=0)  # type: ignore[attr-defined]
        mid = 0.5 * (t0 + t1)
        level = 1 - level if mid - last_end < 0.12 * span else 0
        ax.text(mid, 1.0 + 0.09 * level, s.name.replace("_", " "), transform=ax.get_xaxis_transform(),  # type: ignore[attr-defined]
                ha="center", va="bottom", fontsize=7, color="#555555")
        last_end = mid


def _limits(ax: object, run: GapRun, y_lin: Array) -> None:
    """Keep the view on the measured data when a linear model runs away (the instability run)."""
    lo, hi = float(np.min(run.y)), float(np.max(run.y))
    pad = 0.25 * max(hi - lo, 1e-3)
    if np.min(y_lin) < lo - 2 * pad or np.max(y_lin) > hi + 2 * pad:
        ax.set_ylim(lo - pad, hi + pad)  # type: ignore[attr-defined]


def candidates_figure(d: Diagnosis) -> bytes:
    """Horizontal bars of held-out shrink per candidate, best at the top; the verdict highlighted."""
    cands = sorted(d.candidates, key=lambda c: c.shrink)
    fig = Figure(figsize=(7.0, 0.45 * len(cands) + 1.2))
    ax = fig.subplots()
    y = np.arange(len(cands))
    shrink = np.array([100 * c.shrink for c in cands])
    colours = [AUGMENTED if c.effect == d.verdict.effect else "#8da0cb" for c in cands]
    ax.barh(y, np.clip(shrink, -100, 100), color=colours)
    for yi, c, s in zip(y, cands, shrink):
        ax.text(max(min(s, 100), 0) + 1, yi, f"{0.0 if abs(s) < 0.5 else s:.0f} %  (NRMSE {100 * c.heldout_nrmse_after:.2g} %)", va="center",
                fontsize=8)
    ax.set_yticks(y, [effect_name(c.effect) for c in cands], fontsize=9)
    ax.axvline(0.0, color="#999999", lw=0.6)
    ax.set_xlim(min(-5.0, float(np.clip(shrink.min(), -100, 0)) - 5), 130)
    ax.set_xlabel("held-out gap removed [%] (leave-one-run-out)")
    ax.set_title(f"Candidates ranked by shrink — verdict: {effect_name(d.verdict.effect)}", fontsize=10)
    fig.tight_layout()
    return png(fig)
