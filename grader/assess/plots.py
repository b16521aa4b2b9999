"""The report charts, as PNG bytes (matplotlib, no global pyplot state).

* Diverging stacked bars of the Likert items: centred on neutral (half of the
  neutral share each side of 0), disagree left, agree right, one panel per lab, the
  statements in one order in every lab's panel (by % agree over all labs) so they compare
  across labs.
* The hours-per-week distribution.
* Exam item scores by group, one panel per problem.
"""

from __future__ import annotations

import io
import textwrap
from collections.abc import Sequence

import matplotlib

matplotlib.use("Agg")

import numpy as np
import pandas as pd
from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.colors import to_hex
from matplotlib.figure import Figure
from matplotlib.patches import Patch
from matplotlib.ticker import MaxNLocator

from grader.assess.exam_io import CONTROL, TREATED
from grader.assess.schemas import ExamReport, Hours, RatingStats, SurveyReport

#: ColorBrewer RdBu (colour-blind safe), with a grey neutral, for 5 points.
NEUTRAL_GREY = "#cccccc"
LIKERT_COLOURS_5 = ("#ca0020", "#f4a582", NEUTRAL_GREY, "#92c5de", "#0571b0")
GROUP_COLOURS = {TREATED: "#d95f02", CONTROL: "#1b9e77"}
DPI = 150


def _png(fig: Figure) -> bytes:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=DPI, bbox_inches="tight", metadata={"Software": None})
    return buffer.getvalue()


def _colours(points: int) -> tuple[str, ...]:
    """RdBu from red (1) to blue (points); a visible grey for the neutral midpoint."""
    if points == 5:
        return LIKERT_COLOURS_5
    cmap = colormaps["RdBu"]
    colours = [to_hex(cmap(x)) for x in np.linspace(0.08, 0.92, points)]
    if points % 2:
        colours[points // 2] = NEUTRAL_GREY
    return tuple(colours)


def statement_order(items: Sequence[RatingStats]) -> list[str]:
    """Statements bottom to top: by % agree pooled over every lab that rated them (most agreed on top)."""
    agree: dict[str, float] = {}
    rated: dict[str, int] = {}
    for i in items:
        agree[i.statement] = agree.get(i.statement, 0.0) + (i.pct_agree or 0.0) * i.n
        rated[i.statement] = rated.get(i.statement, 0) + i.n
    return sorted(agree, key=lambda s: (agree[s] / rated[s] if rated[s] else 0.0, s))


def _likert_panel(ax: Axes, items: Sequence[RatingStats], title: str, points: int, order: Sequence[str]) -> None:
    """One panel: a diverging bar per statement of ``order`` (bottom to top)."""
    by_statement = {i.statement: i for i in items}
    labels = {i.statement: i.statement_label for i in items}
    colours = _colours(points)
    mid = (points + 1) / 2
    for y, statement in enumerate(order):
        item = by_statement.get(statement)
        if item is None or item.n == 0:
            text = "no ratings" if item is not None else "not asked for this lab"
            ax.text(0, y, text, ha="center", va="center", fontsize=8, color="#555555")
            continue
        shares = 100.0 * np.array(item.counts) / item.n
        left = -shares[np.arange(1, points + 1) < mid].sum() - shares[np.arange(1, points + 1) == mid].sum() / 2
        start = left
        for share, colour in zip(shares, colours, strict=True):
            ax.barh(y, share, left=left, color=colour, edgecolor="white", linewidth=0.5, height=0.7)
            left += share
        ax.text(start - 1.5, y, f"{item.pct_disagree:.0f}%", ha="right", va="center", fontsize=8, color="#8b0000")
        ax.text(left + 1.5, y, f"{item.pct_agree:.0f}%", ha="left", va="center", fontsize=8, color="#053061")
        ax.annotate(f"n={item.n}", (1.01, y), xycoords=("axes fraction", "data"), ha="left", va="center",
                    fontsize=8, color="#333333")
    ax.set_yticks(range(len(order)), [textwrap.fill(labels.get(s, s), 30) for s in order], fontsize=9)
    ax.set_xlim(-112, 112)
    ax.set_ylim(-0.6, len(order) - 0.4)
    ax.axvline(0, color="#333333", linewidth=0.8)
    ticks = [-100, -50, 0, 50, 100]
    ax.set_xticks(ticks, [f"{abs(t)}%" for t in ticks], fontsize=8)
    ax.set_title(title, fontsize=11, loc="left", fontweight="bold")
    ax.spines[["top", "right", "left"]].set_visible(False)
    ax.tick_params(axis="y", length=0)


def likert_chart(report: SurveyReport) -> bytes:
    """The Likert figure as PNG bytes (see :func:`likert_figure`)."""
    return _png(likert_figure(report))


def likert_figure(report: SurveyReport) -> Figure:
    """Diverging stacked bars, one panel per lab (and one for the overall statements)."""
    lab_order = statement_order(report.items)
    panels: list[tuple[str, Sequence[RatingStats], list[str]]] = [
        (lab.lab_name, [i for i in report.items if i.lab == lab.lab], lab_order) for lab in report.labs
    ]
    if report.overall:
        panels.append(("Overall statements", list(report.overall), statement_order(report.overall)))
    heights = [len(order) + 1.2 for _, _, order in panels]
    fig = Figure(figsize=(9.5, 0.42 * sum(heights) + 1.2), layout="constrained")
    axes = fig.subplots(len(panels), 1, sharex=True, gridspec_kw={"height_ratios": heights})
    for ax, (title, items, order) in zip(np.atleast_1d(axes), panels, strict=True):
        _likert_panel(ax, items, title, report.scale.points, order)
    colours = _colours(report.scale.points)
    handles = [Patch(color=c, label=label) for c, label in zip(colours, report.scale.labels, strict=True)]
    fig.legend(handles=handles, loc="outside lower center", ncol=len(handles), fontsize=8, frameon=False)
    fig.suptitle(
        "Student survey: share of ratings (bars centred on neutral; % disagree left, % agree right)",
        fontsize=11,
    )
    return fig


def hours_chart(hours: Hours) -> bytes:
    """Bar chart of hours per week spent outside lab."""
    fig = Figure(figsize=(7, 3.2), layout="constrained")
    ax = fig.subplots()
    counts = [b.count for b in hours.bins]
    ax.bar(range(len(counts)), counts, color="#4575b4", width=0.8)
    for x, c in enumerate(counts):
        if c:
            ax.text(x, c, str(c), ha="center", va="bottom", fontsize=8)
    ax.set_xticks(range(len(counts)), [b.label.replace(" h", "") for b in hours.bins], fontsize=8, rotation=30)
    ax.set_xlabel("hours per week outside lab")
    ax.set_ylabel("students")
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    median = "" if hours.median is None else f", median {hours.median:g} h (IQR {hours.q1:g}-{hours.q3:g})"
    ax.set_title(f"Hours per week outside lab (n = {hours.n}{median})", fontsize=10)
    ax.spines[["top", "right"]].set_visible(False)
    return _png(fig)


def exam_chart(frame: pd.DataFrame, report: ExamReport) -> bytes:
    """Item scores (% of maximum) by group: box, points and mean, one panel per problem."""
    problems = report.problems
    fig = Figure(figsize=(3.3 * len(problems), 4.2), layout="constrained")
    axes = np.atleast_1d(fig.subplots(1, len(problems), sharey=True))
    rng = np.random.default_rng(0)
    for ax, problem in zip(axes, problems, strict=True):
        sub = frame if problem.problem == "overall" else frame[frame["problem"] == problem.problem]
        groups = [TREATED, CONTROL]
        data = [sub.loc[sub["group"] == g, "score"].to_numpy() for g in groups]
        ax.boxplot(data, positions=[0, 1], widths=0.5, showfliers=False,
                   medianprops={"color": "#333333"}, boxprops={"color": "#777777"})
        for x, (g, values) in enumerate(zip(groups, data, strict=True)):
            jitter = rng.uniform(-0.12, 0.12, size=values.size)
            ax.scatter(x + jitter, values, s=14, alpha=0.75, color=GROUP_COLOURS[g], zorder=3)
            if values.size:
                ax.scatter([x], [values.mean()], marker="D", s=40, color="black", zorder=4)
        ax.set_xticks([0, 1], [f"with lab ref.\nn={len(data[0])}", f"without\nn={len(data[1])}"], fontsize=9)
        g = "" if problem.hedges_g is None else f"\ng = {problem.hedges_g:.2f}, Welch p = {problem.welch_p:.2f}"
        ax.set_title(f"{problem.problem}{g}", fontsize=9)
        ax.set_ylim(-5, 105)
        ax.spines[["top", "right"]].set_visible(False)
    axes[0].set_ylabel("item score (% of maximum)")
    fig.suptitle("Embedded exam question: scores by group (box: median and IQR; ◆ = mean)", fontsize=11)
    return _png(fig)
