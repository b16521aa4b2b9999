"""What a reader sees in the run figures (measurement on top, legends off the data, no colliding
labels, bands from the step on, titles that do not repeat themselves) and in the report's wording."""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import replace

import numpy as np
import pytest
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.text import Text

from grader.gap.diagnose import Analysis
from grader.gap.figures import CandidatesFigure
from grader.gap.plots import RunCanvas, draw_candidates, draw_run, png
from grader.gap.report import candidates_job, render_html, run_job, run_title
from grader.gap.runs import GapRun
from grader.gap.segments import segments_of
from grader.gap.summary import effect_name
from grader.model.params import Controller

from .test_parts import _step_run


def _oscillating_run() -> GapRun:
    t = np.arange(0.0, 2.0, 0.001)
    tau = np.clip(t - 0.1, 0.0, None)
    y = np.where(t >= 0.1, 0.2 - 0.1 * np.cos(2 * np.pi * 25 * tau) * np.exp(0.3 * tau), 0.0)
    r = np.where(t >= 0.1, 0.2, 0.0)
    return GapRun("instability", "instability", Controller(58), t, r, y, None, 0.1, float(np.std(y)), np.zeros(t.size))


def _figure(run: GapRun) -> Figure:
    segs = segments_of(run, 0.0004)
    fig = draw_run(run_job(run, segs, run.y * 1.02, run.y * 0.995, "coulomb_friction"))
    fig.draw_without_rendering()
    return fig


RUNS = {"step": lambda: _step_run(0.3), "instability": _oscillating_run}


@pytest.mark.parametrize("kind", RUNS)
def test_measured_is_drawn_on_top_and_models_thinner(kind: str) -> None:
    top = _figure(RUNS[kind]()).axes[0]
    lines = {line.get_label(): line for line in top.get_lines()}
    measured = lines.pop("measured")
    models = [lines["linear model"], lines["with Coulomb friction"]]
    assert all(measured.get_zorder() > line.get_zorder() for line in lines.values())
    assert all(measured.get_linewidth() > m.get_linewidth() for m in models)


@pytest.mark.parametrize("kind", RUNS)
def test_legend_sits_outside_the_data_panel(kind: str) -> None:
    top = _figure(RUNS[kind]()).axes[0]
    legend = top.get_legend()
    assert legend is not None
    assert legend.get_window_extent().y0 >= top.get_window_extent().y1 - 1


@pytest.mark.parametrize("kind", RUNS)
def test_no_two_labels_overlap(kind: str) -> None:
    fig = _figure(RUNS[kind]())
    hidden = {id(label) for ax in fig.axes for label in _ticklabels_out_of_view(ax)}
    texts = [t for t in fig.findobj(Text) if t.get_visible() and t.get_text().strip() and id(t) not in hidden]
    boxes = [(t.get_text(), t.get_window_extent()) for t in texts]
    clashes = [(a, b) for (a, ba), (b, bb) in itertools.combinations(boxes, 2) if ba.overlaps(bb)]
    assert not clashes


def _ticklabels_out_of_view(ax: Axes) -> list[Text]:
    """Tick labels matplotlib keeps but does not draw (their tick lies outside the view)."""
    lo, hi = sorted(ax.get_ylim())
    return [label for label in ax.get_yticklabels() if not lo <= label.get_position()[1] <= hi]


@pytest.mark.parametrize("kind", RUNS)
def test_segment_bands_start_at_the_step(kind: str) -> None:
    run = RUNS[kind]()
    bottom = _figure(run).axes[1]
    starts = [p.get_x() for p in bottom.patches]
    assert starts and min(starts) >= run.start - 1e-12


def test_a_reused_canvas_draws_the_bytes_a_new_one_draws() -> None:
    """A figure helper draws its runs on one canvas: whatever it drew before (a runaway linear model that fixed
    the limits, other segments, none, models that match the reading exactly or were not simulated, whose residual
    panel holds only the zero line), each run's PNG is the one a new figure gives."""
    step, osc = _step_run(0.3), _oscillating_run()
    shown = run_job(step, segments_of(step, 0.0004), step.y * 1.02, step.y * 0.995, "coulomb_friction")
    runaway = run_job(osc, segments_of(osc, 0.0004), osc.y + np.expm1(3 * osc.t), osc.y, "none")
    nan = np.full(step.n, np.nan)
    jobs = [shown, runaway, replace(shown, bands=(), title="bare"), replace(shown, y_linear=step.y, y_augmented=step.y),
            replace(shown, y_linear=nan, y_augmented=nan, title="not simulated")]
    fresh = [png(draw_run(job), tight=False) for job in jobs]
    assert len(set(fresh)) == len(jobs)
    for before, after in itertools.permutations(range(len(jobs)), 2):
        canvas = RunCanvas()
        png(canvas.show(jobs[before]), tight=False)
        assert png(canvas.show(jobs[after]), tight=False) == fresh[after], (before, after)


def test_titles_do_not_repeat_the_kind() -> None:
    assert run_title(_oscillating_run()) == "instability: Kp = 58"
    assert run_title(_step_run(0.3)) == "s (step run): Kp = 10"


def test_report_says_which_nrmse_is_which_and_what_noise_alone_means(analysed: Callable[..., Analysis]) -> None:
    a = analysed("coulomb_friction", {"coulomb_friction": {"Fc": 2.0}})
    images = {f"run_{r.name}.png": b"" for r in a.runs} | {"candidates.png": b""}
    page = render_html(a, images)
    head = page.split("<h2>Where the gap lies</h2>")[1].split("</tr>")[0]
    assert "whole-run NRMSE" in head and "noise alone" in head
    glossary = page.split("How to read the numbers.")[1].split("</p>")[0]
    for term in ("Whole-run NRMSE", "Held-out NRMSE", "Noise alone", "leave-one-run-out", "reading noise"):
        assert term in glossary


PAIR = "valve deadband + pressure flow nonlinearity"  # the longest name a candidate can have


@pytest.mark.parametrize("shrink, verdict", [((1.0, 0.97, 0.4, -0.00005, -2.5), 0), ((0.3, 0.2, -0.004, -0.6, -1.0), 2),
                                             ((0.999, 0.998, 0.5, 0.1, 0.0), None), ((0.1, 0.2, 0.3, 0.4, 0.5), 1)])
def test_candidates_labels_stay_inside_the_axes_and_the_nrmse_column_beside_them(shrink: tuple[float, ...],
                                                                                  verdict: int | None) -> None:
    """Each bar's shrink label ends inside the axes whatever the shrink (a 72 % label with its NRMSE once crossed the
    right spine), and none reads "-0 %"; the held-out NRMSEs stand right-aligned in a column right of the axes, one
    per bar, without an exponent; the title, with the longest verdict and on three lines where the verdict is named by
    other evidence than the ranking, stays inside the figure and overlaps nothing; no tick passes 100 %."""
    names = ("valve saturation", PAIR, "pressure flow nonlinearity", "no effect", "sampling delay + valve dynamics")
    heldout = (0.0123, 0.02, 1.06, 0.004, 0.0996)
    fig = draw_candidates(CandidatesFigure(names, shrink, heldout, tuple(k == verdict for k in range(5)),
                                           "sensor quantization" if verdict is None else names[verdict]))
    fig.draw_without_rendering()
    ax = fig.axes[0]
    box = ax.get_window_extent()
    bars = [t for t in ax.texts if t.get_transform() == ax.transData]
    column = [t for t in ax.texts if t not in bars]
    assert len(bars) == 5 and len(column) == 6  # five NRMSEs and the column's heading
    for t in bars:
        e = t.get_window_extent()
        assert box.x0 <= e.x0 and e.x1 <= box.x1 and t.get_text() != "-0 %", t.get_text()
    extents = [t.get_window_extent() for t in column]
    assert all(e.x0 > box.x1 for e in extents) and max(e.x1 for e in extents) - min(e.x1 for e in extents) < 0.5
    assert sorted(t.get_text() for t in column if "NRMSE" not in t.get_text()) == sorted(
        ["1.2 %", "2.0 %", "106 %", "0.40 %", "10 %"])  # two digits, trailing zeros kept, no exponent
    title = fig.get_suptitle()
    assert ("other evidence" in title) == (verdict is None)
    top = fig._suptitle.get_window_extent()  # noqa: SLF001 (matplotlib keeps the suptitle's artist there)
    assert fig.bbox.x0 <= top.x0 and top.x1 <= fig.bbox.x1 and top.y1 <= fig.bbox.y1
    assert not any(a.overlaps(b) for a, b in itertools.combinations([*extents, top, box], 2))
    assert max(ax.get_xticks()) <= 100


def test_the_candidates_figure_highlights_the_verdicts_pair_and_names_both(analysed: Callable[..., Analysis]) -> None:
    """A verdict with a second effect names both in the title and highlights the pair's own bar where it was fitted
    (the single effect's bar was highlighted under a title naming only it); a verdict no candidate holds highlights
    nothing."""
    d = analysed("coulomb_friction", {"coulomb_friction": {"Fc": 2.0}}).diagnosis
    first = d.verdict.effect
    pair = d.candidates[-1].model_copy(update={"effect": f"{first}+sampling_delay"})
    both = d.model_copy(update={"candidates": [*d.candidates, pair],
                                "verdict": d.verdict.model_copy(update={"second_effect": "sampling_delay"})})
    job = candidates_job(both)
    assert job.verdict == f"{effect_name(first)} + sampling delay"
    assert [n for n, v in zip(job.names, job.is_verdict) if v] == [effect_name(pair.effect)]
    adc = d.verdict.model_copy(update={"effect": "sensor_quantization"})
    alone = candidates_job(d.model_copy(update={"verdict": adc}))
    assert alone.verdict == "sensor quantization" and not any(alone.is_verdict)
    assert sum(candidates_job(d).is_verdict) == 1


def test_the_augmented_curve_is_labelled_by_what_it_simulates(analysed: Callable[..., object]) -> None:
    """The run plots' augmented model is the verdict's, with the ADC in its loop only where one rule (loop_adc)
    puts it there: an ADC of whole bits that matters. An ADC verdict it cannot simulate (a step of 10.3 bits) is
    drawn as what it is, the re-fitted linear model."""
    from grader.gap.report import _augmented
    from grader.gap.schema import QuantizationInfo, Value

    d = analysed("coulomb_friction", {"coulomb_friction": {"Fc": 2.0}}).diagnosis
    band = Value(value=0.01, unit="in")
    q = QuantizationInfo(adc_step=band, share_of_step=0.1, share_of_readoff=None, bits=10.0, limit_cycle=False,
                         matters=True, steady_state_error_band=band)
    with_adc = d.verdict.model_copy(update={"second_effect": "sensor_quantization"})
    assert _augmented(d.model_copy(update={"verdict": with_adc, "quantization": q})) == \
        "coulomb_friction+sensor_quantization"
    assert _augmented(d.model_copy(update={"verdict": with_adc, "quantization": q.model_copy(
        update={"bits": 10.3})})) == "coulomb_friction"
    adc = d.verdict.model_copy(update={"effect": "sensor_quantization"})
    assert _augmented(d.model_copy(update={"verdict": adc, "quantization": q})) == "sensor_quantization"
    assert _augmented(d.model_copy(update={"verdict": adc, "quantization": q.model_copy(update={"bits": 10.3})})) \
        == "none"
