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
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.patches import Patch
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
#: Line widths [pt]: the measurement is drawn on top, the models thinner under it.
MEASURED_LW, MODEL_LW = 1.5, 0.9


#: The run figure's fixed margins (fractions of 8 × 5.8 in): room for the title and legend above,
#: the segment key below and six-character tick labels with a two-line axis label on the left. A
#: fixed layout draws the figure once; a constrained one draws it twice (a third of the report's time).
RUN_MARGINS = {"left": 0.105, "right": 0.985, "top": 0.89, "bottom": 0.165, "hspace": 0.07}


def png(fig: Figure, *, tight: bool = True) -> bytes:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=DPI, bbox_inches="tight" if tight else None, metadata={"Software": None})
    return buffer.getvalue()


def run_figure(run: GapRun, segs: list[Segment], y_lin: Array, y_aug: Array, effect: str) -> bytes:
    """The run's figure as PNG bytes (see :func:`draw_run`)."""
    return png(draw_run(run, segs, y_lin, y_aug, effect), tight=False)


def draw_run(run: GapRun, segs: list[Segment], y_lin: Array, y_aug: Array, effect: str) -> Figure:
    """Measured (on top) vs the thinner model lines, and their residuals over the shaded segments.

    The legends sit outside the panels so they never cover the data; the segments are named in
    a key under the figure, not by labels over the bands, and their shading starts at the step.
    """
    fig = Figure(figsize=(8.0, 5.8))
    top, bottom = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [3, 2], **RUN_MARGINS})
    t = run.t
    aug_label = f"with {effect_name(effect)}" if effect != "none" else "linear, re-fitted"
    command = top.plot(t, run.r, color="#999999", lw=0.9, ls="--", label="command", zorder=1)
    lin = top.plot(t, y_lin, color=LINEAR, lw=MODEL_LW, label="linear model", zorder=2)
    aug = top.plot(t, y_aug, color=AUGMENTED, lw=MODEL_LW, ls=(0, (4, 2)), label=aug_label, zorder=2)
    measured = top.plot(t, run.y, color=MEASURED, lw=MEASURED_LW, label="measured", zorder=3)
    top.set_ylabel("position [in]")
    top.set_title(run_title(run), fontsize=10, pad=22)
    top.legend(handles=measured + lin + aug + command, fontsize=8, loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=4, frameon=False)
    _limits(top, run, y_lin)
    shown = _shade(bottom, t, segs, run.start)
    bottom.plot(t, 1e3 * (y_lin - run.y), color=LINEAR, lw=0.8)
    bottom.plot(t, 1e3 * (y_aug - run.y), color=AUGMENTED, lw=0.8)
    bottom.axhline(0.0, color="#999999", lw=0.6)
    bottom.set_ylabel("model − measured\n[mil = 0.001 in]")
    bottom.set_xlabel("time [s]")
    keys = [Patch(color=SEGMENT_COLOURS[name], label=name.replace("_", " ")) for name in shown]
    if keys:
        fig.legend(handles=keys, loc="lower center", bbox_to_anchor=(0.5, 0.0), ncol=len(keys), fontsize=8,
                   frameon=False, title="segments (shaded)", title_fontsize=8)
    return fig


def run_title(run: GapRun) -> str:
    """Run name, kind (unless the name already says it) and gains: "instability: Kp = 58"."""
    c = run.controller
    gains = f"Kp = {c.Kp:g}" + (f", Ki = {c.Ki:g}" if c.Ki else "") + (f", Kd = {c.Kd:g}" if c.Kd else "")
    kind = "" if run.kind.lower() in run.name.lower() else f" ({run.kind} run)"
    return f"{run.name}{kind}: {gains}"


def _shade(ax: Axes, t: Array, segs: list[Segment], start: float) -> list[str]:
    """Shade the non-empty segments from the step time on; returns their names in order."""
    shown = []
    for s in segs:
        if s.i1 <= s.i0:
            continue
        t0, t1 = max(float(t[s.i0]), start), float(t[s.i1 - 1])
        if t1 <= t0:
            continue
        ax.axvspan(t0, t1, color=SEGMENT_COLOURS[s.name], lw=0, zorder=0)
        shown.append(s.name)
    return shown


def _limits(ax: Axes, run: GapRun, y_lin: Array) -> None:
    """Keep the view on the measured data when a linear model runs away (the instability run)."""
    lo, hi = float(np.min(run.y)), float(np.max(run.y))
    pad = 0.25 * max(hi - lo, 1e-3)
    if np.min(y_lin) < lo - 2 * pad or np.max(y_lin) > hi + 2 * pad:
        ax.set_ylim(lo - pad, hi + pad)


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
        label = f"{0.0 if abs(s) < 0.5 else s:.0f} %  (held-out NRMSE {100 * c.heldout_nrmse_after:.2g} %)"
        ax.text(max(min(s, 100), 0) + 1, yi, label, va="center", fontsize=8)
    ax.set_yticks(y, [effect_name(c.effect) for c in cands], fontsize=9)
    ax.axvline(0.0, color="#999999", lw=0.6)
    ax.set_xlim(min(-5.0, float(np.clip(shrink.min(), -100, 0)) - 5), 150)
    ax.set_xlabel("held-out gap removed [%] (leave-one-run-out)")
    ax.set_title(f"Candidates ranked by shrink — verdict: {effect_name(d.verdict.effect)}", fontsize=10)
    fig.tight_layout()
    return png(fig)
