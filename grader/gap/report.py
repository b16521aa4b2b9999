"""The diagnosis outputs: ``diagnosis.json``, ``report.html`` (self-contained, PNGs embedded
as base64, no scripts) and the PNG plots beside it (``run_<name>.png``, ``candidates.png``)."""

from __future__ import annotations

import base64
import html
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from grader.gap.figures import CandidatesFigure, Job, PlotHelpers, RunFigure, draw_all, plot_helpers
from grader.gap.quantization import QUANTIZATION, loop_adc
from grader.gap.runs import GapRun
from grader.gap.schema import Diagnosis, diagnosis_json
from grader.gap.segments import Segment
from grader.gap.summary import READOFF_NAMES, combination, effect_name, param_text, show, summary

if TYPE_CHECKING:
    from grader.gap.diagnose import Analysis

Array = NDArray[np.float64]

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
    """The effect(s) the augmented model adds: the verdict, with its second effect when that was fitted too, or when
    it is the ADC the model has in its loop (:func:`~grader.gap.quantization.loop_adc`); an ADC verdict the model
    cannot simulate leaves the re-fitted linear model (``none``)."""
    combo = combination(d)
    if combo is not None:
        return combo.effect
    adc = loop_adc(d.quantization, d.verdict) is not None
    if d.verdict.effect == QUANTIZATION:
        return QUANTIZATION if adc else "none"
    return f"{d.verdict.effect}+{QUANTIZATION}" if adc else d.verdict.effect


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
<div class="verdict">{paras}</div>
{f'<h2 id="notes">Notes on the data</h2><ul>{notes}</ul>' if notes else ""}{_GLOSSARY}
<h2>Where the gap lies</h2>{_gap_table(d)}
<h2>What students read off</h2>{_readoff_table(d)}
<h2>Which effect</h2>{_img(images["candidates.png"], "candidates ranked by shrink")}{_candidate_table(d)}
<h2>Runs: measured, linear and augmented model</h2>
<p>Residuals are shaded by segment; the augmented model adds {html.escape(effect_name(_augmented(d)))}.</p>{runs}
</body></html>
"""


def run_title(run: GapRun) -> str:
    """Run name, kind (unless the name already says it) and gains: "instability: Kp = 58"."""
    c = run.controller
    gains = f"Kp = {c.Kp:g}" + (f", Ki = {c.Ki:g}" if c.Ki else "") + (f", Kd = {c.Kd:g}" if c.Kd else "")
    kind = "" if run.kind.lower() in run.name.lower() else f" ({run.kind} run)"
    return f"{run.name}{kind}: {gains}"


def bands(run: GapRun, segs: list[Segment]) -> tuple[tuple[str, float, float], ...]:
    """The non-empty segments as shaded bands (name, t0 [s], t1 [s]), each from the step time on."""
    out = []
    for s in segs:
        if s.i1 <= s.i0:
            continue
        t0, t1 = max(float(run.t[s.i0]), run.start), float(run.t[s.i1 - 1])
        if t1 > t0:
            out.append((s.name, t0, t1))
    return tuple(out)


def run_job(run: GapRun, segs: list[Segment], y_lin: Array, y_aug: Array, effect: str) -> RunFigure:
    """What the run's figure shows, with the augmented model labelled by its ``effect``."""
    label = f"with {effect_name(effect)}" if effect != "none" else "linear, re-fitted"
    return RunFigure(run.t, run.r, run.y, y_lin, y_aug, run_title(run), label, run.start, bands(run, segs))


def candidates_job(d: Diagnosis) -> CandidatesFigure:
    """What the candidates' figure shows."""
    c, v = d.candidates, d.verdict
    named = v.effect if v.second_effect is None else f"{v.effect}+{v.second_effect}"
    bar = named if any(x.effect == named for x in c) else v.effect  # the pair's own bar where it was fitted
    return CandidatesFigure(tuple(effect_name(x.effect) for x in c), tuple(x.shrink for x in c),
                            tuple(x.heldout_nrmse_after for x in c), tuple(x.effect == bar for x in c),
                            effect_name(named))


def _render_plots(analysis: Analysis, helpers: PlotHelpers | None) -> dict[str, bytes]:
    """Every PNG of the report by file name, drawn by the ``helpers`` (see :func:`draw_all`)."""
    d = analysis.diagnosis
    jobs: dict[str, Job] = {
        f"run_{r.name}.png": run_job(r, s, yl, ya, _augmented(d))
        for r, s, yl, ya in zip(analysis.runs, analysis.segments, analysis.y_linear, analysis.y_augmented)}
    jobs["candidates.png"] = candidates_job(d)
    return dict(zip(jobs, draw_all(list(jobs.values()), helpers)))


def write_outputs(analysis: Analysis, out: Path, *, helpers: PlotHelpers | None = None) -> list[Path]:
    """Write diagnosis.json, report.html and the PNGs into ``out``; returns the paths written. The figures
    are drawn by the given :func:`~grader.gap.figures.plot_helpers` (default: helpers started now)."""
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
