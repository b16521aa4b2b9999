"""The diagnosis outputs: ``diagnosis.json``, ``report.html`` (self-contained, PNGs embedded
as base64, no scripts) and the PNG plots beside it (``run_<name>.png``, ``candidates.png``)."""

from __future__ import annotations

import base64
import html
import importlib
import multiprocessing as mp
import os
from collections.abc import Iterator
from concurrent.futures import BrokenExecutor, ProcessPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from grader.gap.schema import Diagnosis, diagnosis_json
from grader.gap.summary import READOFF_NAMES, combination, effect_name, param_text, show, summary

if TYPE_CHECKING:
    from grader.gap.diagnose import Analysis

_CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;margin:2rem auto;max-width:60rem;
padding:0 1rem;color:#222;line-height:1.45}
h1{font-size:1.5rem}h2{font-size:1.2rem;margin-top:2rem;border-bottom:1px solid #ddd}
table{border-collapse:collapse;font-size:.85rem;margin:.5rem 0 1rem}
th,td{border:1px solid #ddd;padding:.25rem .5rem;vertical-align:top}th{background:#f3f3f3;text-align:left}
td.n{text-align:right;font-variant-numeric:tabular-nums;white-space:nowrap}img{max-width:100%;height:auto}
.verdict{background:#eef7f1;border-left:4px solid #1b9e77;padding:.5rem 1rem}.meta{color:#555;font-size:.85rem}
"""


def _img(data: bytes, alt: str) -> str:
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{base64.b64encode(data).decode()}">'


def _table(head: list[str], rows: list[list[str]], numeric: set[int] | None = None) -> str:
    numeric = numeric or set()
    th = "".join(f"<th>{html.escape(h)}</th>" for h in head)
    body = "".join(
        "<tr>" + "".join(f'<td{" class=n" if j in numeric else ""}>{html.escape(c)}</td>' for j, c in enumerate(r)) + "</tr>"
        for r in rows
    )
    return f"<table><tr>{th}</tr>{body}</table>"


#: What the report's two NRMSEs and the "noise alone" column mean (shown under the verdict).
_GLOSSARY = """<p class="meta">How to read the numbers. NRMSE = ‖measured − model‖ / ‖measured − its mean‖ over a run
(0 % is a perfect model; fit = 100 % − NRMSE). <b>Whole-run NRMSE</b> (“Where”, and the table below): the
linear model named above, simulated over each complete run as it is, fitted to nothing; the overall figure is the
root-mean-square over runs. <b>Held-out NRMSE</b> (“How far it shrinks”, and the candidates): each run predicted
by a model whose parameters (β/Vt, Kce, Kq and the effect's own) were fitted to the other runs only
(leave-one-run-out), typical value (geometric mean) over runs; it is lower than the whole-run figure because the
fit also corrects the linear parameters. <b>Noise alone</b>: the NRMSE that even a perfect model would show
because of the reading noise (the noise σ above divided by the run's standard deviation); a run whose NRMSE
is close to it has no gap left to explain.</p>"""


def _pct(x: float) -> str:
    return f"{100 * x:.3g} %"


def _gap_table(d: Diagnosis) -> str:
    rows = []
    for g in d.gap.by_run:
        segs = ", ".join(f"{s.segment.replace('_', ' ')} {_pct(s.share)}" for s in g.segments if s.samples)
        rows.append([g.run, g.kind, _pct(g.nrmse), f"{g.fit_percent:.1f} %", _pct(g.noise_nrmse), segs])
    return _table(["run", "kind", "whole-run NRMSE", "fit", "noise alone", "share of the squared gap by segment"], rows,
                  {2, 3, 4})


def _readoff_table(d: Diagnosis) -> str:
    def v(x: float | None, unit: str) -> str:
        return "–" if x is None else show(x, unit)

    rows = [[READOFF_NAMES[r.quantity], r.run, v(r.measured, r.unit), v(r.predicted, r.unit), v(r.augmented, r.unit)]
            for r in d.readoffs]
    return _table(["quantity", "run", "measured", "linear model", "augmented model"], rows, {2, 3, 4})


def _candidate_table(d: Diagnosis) -> str:
    rows = []
    for c in d.candidates:
        params = "; ".join(param_text(k, p) for k, p in c.params.items()) or "–"
        lin = "; ".join(param_text(k, p) for k, p in c.linear_params.items())
        rows.append([effect_name(c.effect), params, lin, _pct(c.fit_nrmse), _pct(c.heldout_nrmse_after), _pct(c.shrink)])
    return _table(["candidate", "fitted effect (95 %)", "re-fitted β/Vt, Kce, Kq (95 %)", "fit NRMSE", "held-out NRMSE",
                   "shrink"], rows, {3, 4, 5})


def _augmented(d: Diagnosis) -> str:
    """The effect(s) the augmented model adds: the verdict, with its second effect when that was fitted too."""
    combo = combination(d)
    return d.verdict.effect if combo is None else combo.effect


def render_html(analysis: Analysis, images: dict[str, bytes]) -> str:
    """The report page."""
    d = analysis.diagnosis
    paras = "".join(f"<p>{html.escape(p)}</p>" for p in summary(d).split("\n\n")[1:])
    runs = "".join(f"<h3>{html.escape(r.name)}</h3>{_img(images[f'run_{r.name}.png'], r.name)}" for r in analysis.runs)
    notes = "".join(f"<li>{html.escape(n)}</li>" for n in d.notes)
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>Diagnosis of {html.escape(d.dataset)}</title>
<style>{_CSS}</style></head><body>
<h1>Sim-to-real diagnosis of {html.escape(d.dataset)}</h1>
<p class="meta">Station {html.escape(d.station)} · linear model: {html.escape(d.baseline.method)} ·
noise σ ≈ {show(d.noise.sigma.value, "in")} · grader {html.escape(d.generated_by.get("version", ""))}</p>
<div class="verdict">{paras}</div>{_GLOSSARY}
<h2>Where the gap lies</h2>{_gap_table(d)}
<h2>What students read off</h2>{_readoff_table(d)}
<h2>Which effect</h2>{_img(images["candidates.png"], "candidates ranked by shrink")}{_candidate_table(d)}
<h2>Runs: measured, linear and augmented model</h2>
<p>Residuals are shaded by segment; the augmented model adds {html.escape(effect_name(_augmented(d)))}.</p>{runs}
{f"<h2>Notes</h2><ul>{notes}</ul>" if notes else ""}
</body></html>
"""


def _plot(job: tuple[Any, ...]) -> bytes:
    """One PNG: ``("run", run, segments, y_linear, y_augmented, effect)`` or ``("candidates", diagnosis)``."""
    from grader.gap import plots  # matplotlib: imported where the figures are drawn

    return plots.run_figure(*job[1:]) if job[0] == "run" else plots.candidates_figure(*job[1:])


@dataclass(frozen=True)
class PlotHelpers:
    """Forked helper processes and the index of the next figure to draw, shared with them."""

    pool: ProcessPoolExecutor
    size: int
    next_figure: Any  # multiprocessing.Value("i")


_NEXT: Any = None  # in a helper: its PlotHelpers.next_figure


def _warm(next_figure: Any) -> None:
    global _NEXT
    _NEXT = next_figure
    importlib.import_module("grader.gap.plots")  # matplotlib, imported while the parent still works


def _claim(next_figure: Any) -> int:
    with next_figure.get_lock():
        k = int(next_figure.value)
        next_figure.value = k + 1
    return k


def _drain(jobs: list[tuple[Any, ...]], next_figure: Any = None) -> dict[int, bytes]:
    """Draw figures in the order claimed, until none is left: {index: PNG}."""
    counter = _NEXT if next_figure is None else next_figure
    out = {}
    while (k := _claim(counter)) < len(jobs):
        out[k] = _plot(jobs[k])
    return out


@contextmanager
def plot_helpers() -> Iterator[PlotHelpers | None]:
    """Helper processes for the report's figures, forked now (one per core but this one's, at most
    three) and importing matplotlib at once: started before the diagnosis, they are ready when it ends
    (:func:`grader.gap.diagnose.analyse` never needs matplotlib). None where fork or a second core is missing."""
    cpus = os.cpu_count() or 1
    if cpus < 2 or "fork" not in mp.get_all_start_methods():
        yield None
        return
    ctx = mp.get_context("fork")
    size, next_figure = min(cpus - 1, 3), ctx.Value("i", 0)
    with ProcessPoolExecutor(size, mp_context=ctx, initializer=_warm, initargs=(next_figure,)) as pool:
        for _ in range(size):
            pool.submit(int)  # start every helper now
        yield PlotHelpers(pool, size, next_figure)


def _render_plots(analysis: Analysis, helpers: PlotHelpers | None) -> dict[str, bytes]:
    """Every PNG of the report, drawn by this process and the ``helpers`` together, each claiming the next
    figure not yet claimed (matplotlib is single-threaded and the figures are independent; the bytes do
    not depend on who draws which). A figure a helper took with it when it died is drawn here."""
    d = analysis.diagnosis
    jobs: dict[str, tuple[Any, ...]] = {
        f"run_{r.name}.png": ("run", r, s, yl, ya, _augmented(d))
        for r, s, yl, ya in zip(analysis.runs, analysis.segments, analysis.y_linear, analysis.y_augmented)}
    jobs["candidates.png"] = ("candidates", d)
    todo = list(jobs.values())
    if helpers is None:
        drawn = {k: _plot(job) for k, job in enumerate(todo)}
    else:
        helpers.next_figure.value = 0
        offered = []
        try:
            offered += [helpers.pool.submit(_drain, todo) for _ in range(helpers.size)]
        except BrokenExecutor:  # a helper died earlier: no more help
            pass
        drawn = _drain(todo, helpers.next_figure)
        for future in offered:
            try:
                drawn.update(future.result())
            except BrokenExecutor:
                pass
        drawn.update({k: _plot(job) for k, job in enumerate(todo) if k not in drawn})
    return {name: drawn[k] for k, name in enumerate(jobs)}


def write_outputs(analysis: Analysis, out: Path, *, helpers: PlotHelpers | None = None) -> list[Path]:
    """Write diagnosis.json, report.html and the PNGs into ``out``; returns the paths written. The figures
    are drawn with the given :func:`plot_helpers` (default: helpers started now)."""
    out.mkdir(parents=True, exist_ok=True)
    d = analysis.diagnosis
    if helpers is None:
        with plot_helpers() as started:
            images = _render_plots(analysis, started)
    else:
        images = _render_plots(analysis, helpers)
    written = []
    for name, data in images.items():
        (out / name).write_bytes(data)
        written.append(out / name)
    (out / "diagnosis.json").write_text(diagnosis_json(d), encoding="utf-8")
    (out / "report.html").write_text(render_html(analysis, images), encoding="utf-8")
    return [out / "diagnosis.json", out / "report.html", *written]
