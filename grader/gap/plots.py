"""The diagnosis plots, as PNG bytes (matplotlib Agg, no global pyplot state).

* One figure per run: measured vs the linear model vs the augmented model (the verdict's
  effect), and below it the residuals of both models with the run's segments shaded.
* The candidates ranked by held-out shrink.
"""

from __future__ import annotations

import io
import math
import threading

import matplotlib

matplotlib.use("Agg")

import numpy as np
from matplotlib.artist import Artist
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Patch
from matplotlib.transforms import blended_transform_factory, offset_copy
from numpy.typing import NDArray
from PIL import Image

from grader.gap.figures import CandidatesFigure, RunFigure

Array = NDArray[np.float64]
DPI = 130
PNG_LEVEL = 3
#: Margin [in] a cropped figure keeps around its content (matplotlib's ``savefig.pad_inches``).
TIGHT_PAD = 0.1
SEGMENT_COLOURS = {"rise": "#e0ecf4", "overshoot": "#fde0dd", "settling": "#fff7bc", "steady_state": "#e5f5e0",
                   "tracking": "#efedf5", "oscillation": "#fee6ce"}
MEASURED, LINEAR, AUGMENTED = "#222222", "#d95f02", "#1b9e77"
#: Line widths [pt]: the measurement is drawn on top, the models thinner under it.
MEASURED_LW, MODEL_LW = 1.5, 0.9


#: The run figure's fixed margins (fractions of 8 × 5.8 in): room for the title and legend above,
#: the segment key below and six-character tick labels with a two-line axis label on the left. A
#: fixed layout draws the figure once; a constrained one draws it twice (a third of the report's time).
RUN_MARGINS = {"left": 0.105, "right": 0.985, "top": 0.89, "bottom": 0.165, "hspace": 0.07}
#: Each thread's :class:`RunCanvas` (a figure helper draws several runs).
_REUSED = threading.local()


def png(fig: Figure, *, tight: bool = True) -> bytes:
    """PNG bytes at :data:`DPI`, drawn once; ``tight`` crops the drawing to its content and :data:`TIGHT_PAD`
    around it (as ``savefig(bbox_inches="tight")`` would, drawing it twice). Stored as RGB: the figures are
    opaque, and an alpha channel would cost a third more time to compress. zlib level :data:`PNG_LEVEL`: a third
    less time than the default 6 for a tenth more bytes."""
    fig.set_dpi(DPI)
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    pixels = np.asarray(canvas.buffer_rgba())
    if tight:
        height, width = pixels.shape[:2]
        box = fig.get_tightbbox(canvas.get_renderer()).padded(TIGHT_PAD)  # [in], from the bottom left
        x0, x1 = max(math.floor(box.x0 * DPI), 0), min(math.ceil(box.x1 * DPI), width)
        y0, y1 = max(math.floor(height - box.y1 * DPI), 0), min(math.ceil(height - box.y0 * DPI), height)
        pixels = pixels[y0:y1, x0:x1]
    buffer = io.BytesIO()
    Image.fromarray(pixels).convert("RGB").save(buffer, format="png", dpi=(DPI, DPI), compress_level=PNG_LEVEL)
    return buffer.getvalue()


def run_figure(data: RunFigure) -> bytes:
    """The run's figure as PNG bytes (see :func:`draw_run`), drawn on this thread's :class:`RunCanvas`: the
    same bytes as on a new one, in a fifth less time."""
    canvas = getattr(_REUSED, "canvas", None)
    if canvas is None:
        canvas = _REUSED.canvas = RunCanvas()
    return png(canvas.show(data), tight=False)


def draw_run(data: RunFigure) -> Figure:
    """The run's figure on a new :class:`RunCanvas`."""
    return RunCanvas().show(data)


class RunCanvas:
    """A run figure's panels and lines, shown again for each run: measured (on top) vs the thinner model lines,
    and their residuals over the shaded segments.

    The legends sit outside the panels so they never cover the data; the segments are named in a key under the
    figure, not by labels over the bands, and their shading starts at the step. The panels, lines and ticks are
    made once (a fifth of a figure's time); :meth:`show` replaces the data, title, legends and bands, and
    rescales both panels as a new figure would.
    """

    def __init__(self) -> None:
        self.fig = Figure(figsize=(8.0, 5.8))
        self.top, self.bottom = self.fig.subplots(2, 1, sharex=True,
                                                  gridspec_kw={"height_ratios": [3, 2], **RUN_MARGINS})
        top, bottom = self.top, self.bottom
        self.command, = top.plot([], [], color="#999999", lw=0.9, ls="--", label="command", zorder=1)
        self.linear, = top.plot([], [], color=LINEAR, lw=MODEL_LW, label="linear model", zorder=2)
        self.augmented, = top.plot([], [], color=AUGMENTED, lw=MODEL_LW, ls=(0, (4, 2)), zorder=2)
        self.measured, = top.plot([], [], color=MEASURED, lw=MEASURED_LW, label="measured", zorder=3)
        top.set_ylabel("position [in]")
        self.gap_linear, = bottom.plot([], [], color=LINEAR, lw=0.8)
        self.gap_augmented, = bottom.plot([], [], color=AUGMENTED, lw=0.8)
        bottom.axhline(0.0, color="#999999", lw=0.6)
        bottom.set_ylabel("model − measured\n[mil = 0.001 in]")
        bottom.set_xlabel("time [s]")
        self.shown: list[Artist] = []  # the bands and the segment key of the run shown

    def show(self, data: RunFigure) -> Figure:
        """The figure with ``data``'s run in it."""
        for artist in self.shown:
            artist.remove()
        top, bottom = self.top, self.bottom
        t, y, y_lin, y_aug = data.t, data.y, data.y_linear, data.y_augmented
        self.command.set_data(t, data.r)
        self.linear.set_data(t, y_lin)
        self.augmented.set_data(t, y_aug)
        self.augmented.set_label(data.augmented_label)
        self.measured.set_data(t, y)
        self.gap_linear.set_data(t, 1e3 * (y_lin - y))
        self.gap_augmented.set_data(t, 1e3 * (y_aug - y))
        top.set_title(data.title, fontsize=10, pad=22, y=1.0)  # a fixed y: no search for top tick labels to avoid
        top.legend(handles=[self.measured, self.linear, self.augmented, self.command], fontsize=8,
                   loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=4, frameon=False)
        self.shown = [bottom.axvspan(t0, t1, color=SEGMENT_COLOURS[name], lw=0, zorder=0)
                      for name, t0, t1 in data.bands]
        keys = [Patch(color=SEGMENT_COLOURS[name], label=name.replace("_", " ")) for name, _, _ in data.bands]
        if keys:
            self.shown.append(self.fig.legend(handles=keys, loc="lower center", bbox_to_anchor=(0.5, 0.0),
                                              ncol=len(keys), fontsize=8, frameon=False, title="segments (shaded)",
                                              title_fontsize=8))
        for ax in (top, bottom):  # a new figure's unit view first: the zero line's limits pass through it
            ax.set_xlim(0.0, 1.0)
            ax.set_ylim(0.0, 1.0)
        for ax in (top, bottom):
            ax.relim()
            ax.set_autoscale_on(True)
            ax.autoscale_view()
        _limits(top, y, y_lin)
        return self.fig


def _limits(ax: Axes, y: Array, y_lin: Array) -> None:
    """Keep the view on the measured data when a linear model runs away (the instability run)."""
    lo, hi = float(np.min(y)), float(np.max(y))
    pad = 0.25 * max(hi - lo, 1e-3)
    if np.min(y_lin) < lo - 2 * pad or np.max(y_lin) > hi + 2 * pad:
        ax.set_ylim(lo - pad, hi + pad)


def warm() -> None:
    """Draw a throwaway run figure and candidates' figure: the fonts load and this thread's :class:`RunCanvas` is
    made before the first real figure (a helper does this while the diagnosis still works; the first figure
    took twice as long as the next)."""
    t = np.linspace(0.0, 1.0, 200)
    y = 1.0 - np.exp(-10 * t)
    bands = tuple((name, 0.2 * k, 0.2 * k + 0.1) for k, name in enumerate(SEGMENT_COLOURS))
    run_figure(RunFigure(t, np.ones_like(t), y, 0.99 * y, 1.01 * y, "warm-up: Kp = 1", "with a lag", 0.0, bands))
    candidates_figure(CandidatesFigure(("a", "b"), (0.5, -0.2), (0.01, 0.02), (True, False), "a"))


def candidates_figure(data: CandidatesFigure) -> bytes:
    """The candidates' figure (:func:`draw_candidates`) as PNG bytes."""
    return png(draw_candidates(data))


#: Where the held-out NRMSE column's right edge stands [pt] right of the axes.
COLUMN_RIGHT = 46.0
#: Shrink [%] from which a bar's label is drawn inside its end.
INSIDE = 60.0


def _nrmse_text(v: float) -> str:
    """A held-out NRMSE [%] to two significant digits, trailing zeros kept ("0.40", "2.0"), whole numbers from 10 up
    ("101"), never an exponent."""
    text = np.format_float_positional(v, precision=2, unique=False, fractional=False, trim="k")
    return f"{v:.0f}" if text.endswith(".") else text


def draw_candidates(data: CandidatesFigure) -> Figure:
    """Horizontal bars of held-out shrink per candidate, best at the top, each labelled with its shrink; the verdict
    highlighted; each one's held-out NRMSE in a right-aligned column right of the axes; the title above both, the
    verdict on its own line."""
    order = sorted(range(len(data.names)), key=lambda i: data.shrink[i])
    fig = Figure(figsize=(7.0, 0.45 * len(order) + 1.5))
    ax = fig.subplots()
    y = np.arange(len(order))
    shrink = np.array([100 * data.shrink[i] for i in order])
    colours = [AUGMENTED if data.is_verdict[i] else "#8da0cb" for i in order]
    ax.barh(y, np.clip(shrink, -100, 100), color=colours)
    column = offset_copy(blended_transform_factory(ax.transAxes, ax.transData), fig=fig, x=COLUMN_RIGHT, units="points")
    for yi, i, s in zip(y, order, shrink):
        label = f"{round(s) + 0:.0f} %"  # + 0: no "-0"
        if s >= INSIDE:  # at the end of a long bar, inside it (outside it could cross the axes' edge)
            ax.text(min(s, 100) - 1, yi, label, va="center", ha="right", fontsize=8)
        else:
            ax.text(max(s, 0) + 1, yi, label, va="center", fontsize=8)
        ax.text(1.0, yi, f"{_nrmse_text(100 * data.heldout[i])} %", transform=column, va="center", ha="right",
                fontsize=8)
    ax.text(1.0, 1.0, "held-out\nNRMSE", transform=offset_copy(ax.transAxes, fig=fig, x=COLUMN_RIGHT, units="points"),
            va="bottom", ha="right", fontsize=8)
    ax.set_yticks(y, [data.names[i] for i in order], fontsize=9)
    ax.axvline(0.0, color="#999999", lw=0.6)
    left = min(-5.0, float(np.clip(shrink.min(), -100, 0)) - 5)
    ax.set_xlim(left, 105)
    ax.set_xticks([t for t in ax.get_xticks() if left <= t <= 100])  # no tick beyond what a shrink can reach
    ax.set_xlabel("held-out gap removed [%] (leave-one-run-out)")
    title = f"Candidates ranked by shrink\nverdict: {data.verdict}"
    if not any(data.is_verdict):  # viscous friction or the ADC, named by other evidence than these fits
        title += "\n(named by other evidence than this ranking: see the summary)"
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig
