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
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Patch
from numpy.typing import NDArray
from PIL import Image

from grader.gap.figures import CandidatesFigure, RunFigure

Array = NDArray[np.float64]
DPI = 130
PNG_LEVEL = 3
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
    """PNG bytes at :data:`DPI`; ``tight`` crops to the drawn content. An untrimmed figure is stored as RGB:
    the figures are opaque, and an alpha channel would cost a third more time to compress. zlib level
    :data:`PNG_LEVEL`: a third less time than the default 6 for a tenth more bytes."""
    buffer = io.BytesIO()
    if tight:
        fig.savefig(buffer, format="png", dpi=DPI, bbox_inches="tight", metadata={"Software": None},
                    pil_kwargs={"compress_level": PNG_LEVEL})
        return buffer.getvalue()
    fig.set_dpi(DPI)
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    Image.fromarray(np.asarray(canvas.buffer_rgba())).convert("RGB").save(buffer, format="png", dpi=(DPI, DPI),
                                                                            compress_level=PNG_LEVEL)
    return buffer.getvalue()


def run_figure(data: RunFigure) -> bytes:
    """The run's figure as PNG bytes (see :func:`draw_run`)."""
    return png(draw_run(data), tight=False)


def draw_run(data: RunFigure) -> Figure:
    """Measured (on top) vs the thinner model lines, and their residuals over the shaded segments.

    The legends sit outside the panels so they never cover the data; the segments are named in
    a key under the figure, not by labels over the bands, and their shading starts at the step.
    """
    fig = Figure(figsize=(8.0, 5.8))
    top, bottom = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [3, 2], **RUN_MARGINS})
    t, y, y_lin, y_aug = data.t, data.y, data.y_linear, data.y_augmented
    command = top.plot(t, data.r, color="#999999", lw=0.9, ls="--", label="command", zorder=1)
    lin = top.plot(t, y_lin, color=LINEAR, lw=MODEL_LW, label="linear model", zorder=2)
    aug = top.plot(t, y_aug, color=AUGMENTED, lw=MODEL_LW, ls=(0, (4, 2)), label=data.augmented_label, zorder=2)
    measured = top.plot(t, y, color=MEASURED, lw=MEASURED_LW, label="measured", zorder=3)
    top.set_ylabel("position [in]")
    top.set_title(data.title, fontsize=10, pad=22, y=1.0)  # a fixed y: no search for top tick labels to avoid
    top.legend(handles=measured + lin + aug + command, fontsize=8, loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=4, frameon=False)
    _limits(top, y, y_lin)
    for name, t0, t1 in data.bands:
        bottom.axvspan(t0, t1, color=SEGMENT_COLOURS[name], lw=0, zorder=0)
    bottom.plot(t, 1e3 * (y_lin - y), color=LINEAR, lw=0.8)
    bottom.plot(t, 1e3 * (y_aug - y), color=AUGMENTED, lw=0.8)
    bottom.axhline(0.0, color="#999999", lw=0.6)
    bottom.set_ylabel("model − measured\n[mil = 0.001 in]")
    bottom.set_xlabel("time [s]")
    keys = [Patch(color=SEGMENT_COLOURS[name], label=name.replace("_", " ")) for name, _, _ in data.bands]
    if keys:
        fig.legend(handles=keys, loc="lower center", bbox_to_anchor=(0.5, 0.0), ncol=len(keys), fontsize=8,
                   frameon=False, title="segments (shaded)", title_fontsize=8)
    return fig


def _limits(ax: Axes, y: Array, y_lin: Array) -> None:
    """Keep the view on the measured data when a linear model runs away (the instability run)."""
    lo, hi = float(np.min(y)), float(np.max(y))
    pad = 0.25 * max(hi - lo, 1e-3)
    if np.min(y_lin) < lo - 2 * pad or np.max(y_lin) > hi + 2 * pad:
        ax.set_ylim(lo - pad, hi + pad)


def candidates_figure(data: CandidatesFigure) -> bytes:
    """Horizontal bars of held-out shrink per candidate, best at the top; the verdict highlighted."""
    order = sorted(range(len(data.names)), key=lambda i: data.shrink[i])
    fig = Figure(figsize=(7.0, 0.45 * len(order) + 1.2))
    ax = fig.subplots()
    y = np.arange(len(order))
    shrink = np.array([100 * data.shrink[i] for i in order])
    colours = [AUGMENTED if data.is_verdict[i] else "#8da0cb" for i in order]
    ax.barh(y, np.clip(shrink, -100, 100), color=colours)
    for yi, i, s in zip(y, order, shrink):
        label = f"{0.0 if abs(s) < 0.5 else s:.0f} %  (held-out NRMSE {100 * data.heldout[i]:.2g} %)"
        ax.text(max(min(s, 100), 0) + 1, yi, label, va="center", fontsize=8)
    ax.set_yticks(y, [data.names[i] for i in order], fontsize=9)
    ax.axvline(0.0, color="#999999", lw=0.6)
    ax.set_xlim(min(-5.0, float(np.clip(shrink.min(), -100, 0)) - 5), 150)
    ax.set_xlabel("held-out gap removed [%] (leave-one-run-out)")
    ax.set_title(f"Candidates ranked by shrink — verdict: {data.verdict}", fontsize=10)
    fig.tight_layout()
    return png(fig)
