"""Plain-text tables of the withheld-effect benchmark's results (strict scoring, see :mod:`grader.gap.bench`)."""

from __future__ import annotations

from collections import Counter

import numpy as np
from statsmodels.stats.proportion import proportion_confint

from grader.gap.bench import ERROR, SWEEP, Case
from grader.gap.candidates import NONE

ABBREV = {"none": "none", "sampling_delay": "delay", "valve_saturation": "sat", "valve_hysteresis": "hyst",
          "valve_dynamics": "vdyn", "valve_deadband": "dband", "pressure_flow_nonlinearity": "pq",
          "coulomb_friction": "coul", "viscous_friction": "visc", "sensor_quantization": "quant"}


def _pct(x: float) -> str:
    return "–" if np.isnan(x) else f"{100 * x:.1f} %"


def _mean(flags: list[bool]) -> float:
    return float(np.mean(flags)) if flags else float("nan")


def _wilson(flags: list[bool]) -> str:
    """The 95 % Wilson interval of the share of ``flags`` that hold: the sampling error of a rate measured on this
    many datasets (one false positive in 25 is 4 %, and its interval reaches 20 %)."""
    if not flags:
        return "–"
    lo, hi = proportion_confint(int(np.sum(flags)), len(flags), alpha=0.05, method="wilson")
    return f"{100 * lo:.1f}–{100 * hi:.1f} %"


def _interval(flags: list[bool]) -> str:
    """The count of ``flags`` that hold, of how many, and :func:`_wilson`'s interval."""
    return f"{int(np.sum(flags))}/{len(flags)}, {_wilson(flags)}" if flags else "–"


def _confusion(cases: list[Case]) -> str:
    truths = list(dict.fromkeys(c.truth for c in cases))
    verdicts = list(dict.fromkeys([NONE, *truths, *[c.verdict for c in cases]]))
    counts = Counter((c.truth, c.verdict) for c in cases)
    corner = "truth \\ verdict"
    lines = [f"{corner:28s}" + "".join(f"{ABBREV.get(v, v)[:6]:>7s}" for v in verdicts) + "   strict top-1"]
    for t in truths:
        row = [c for c in cases if c.truth == t]
        lines.append(f"{t:28s}" + "".join(f"{counts[(t, v)]:7d}" for v in verdicts) + f"   {_pct(_mean([c.right for c in row]))}")
    return "\n".join(lines)


def _pairs(pairs: list[Case]) -> str:
    if not pairs:
        return ""
    lines = ["two-effect datasets: named (verdict + second effect; ~ a lookalike not told apart)"]
    for c in pairs:
        lines.append(f"  {'ok  ' if c.right else 'MISS'} {c.truth:48s} -> {'+'.join(c.named)}"
                     f"{''.join(f' ~{t}' for t in c.ties)}")
    return "\n".join(lines)


def _headline(singles: list[Case], pairs: list[Case], cli: list[float], cores: int) -> str:
    every = singles + pairs
    top2 = _mean([c.truth in (c.verdict, c.runner_up) for c in singles])
    nones = [c for c in singles if c.truth == NONE]
    shrink = [c.shrink for c in every if c.verdict not in (NONE, ERROR)]
    secs = np.array([c.seconds for c in every])
    first_right = _mean([c.verdict in c.truths for c in pairs])
    false_pos = [c.verdict != NONE or c.second is not None for c in nones]
    return "\n".join([
        f"datasets: {len(every)} ({len(singles)} with one effect or none, {len(pairs)} with two effects); "
        f"diagnoses that failed: {sum(c.verdict == ERROR for c in every)}",
        f"strict top-1 (one effect or none): {_pct(_mean([c.right for c in singles]))}   strict top-2: {_pct(top2)}",
        f"false positives on none: {_pct(_mean(false_pos))} ({len(nones)} datasets)",
        f"named exactly but not told apart from a lookalike (counted as misses): "
        f"{sum(c.named_exactly and not c.right for c in singles)} of one effect or none, "
        f"{sum(c.named_exactly and not c.right for c in pairs)} of two",
        f"two effects, both named: {_pct(_mean([c.right for c in pairs]))}   "
        f"verdict one of the two: {_pct(first_right)} ({len(pairs)} datasets)",
        f"95 % Wilson intervals of these rates (their sampling error): strict top-1 "
        f"{_interval([c.right for c in singles])}; false positives on none {_interval(false_pos)}; "
        f"both named {_interval([c.right for c in pairs])}",
        f"median held-out shrink (verdicts naming an effect; the pair's where two are named): "
        f"{_pct(float(np.median(shrink)) if shrink else float('nan'))} "
        f"({len(shrink)} verdicts)",
        (f"seconds per diagnosis ({cores} core{'s' if cores > 1 else ''}, no report): median {np.median(secs):.2f}, "
         f"90th percentile {np.percentile(secs, 90):.2f}, max {secs.max():.2f}") if secs.size else "seconds per diagnosis: –",
        *([f"seconds of `grader diagnose` (new process, report included) on {len(cli)} datasets: median "
           f"{np.median(cli):.2f}, 90th percentile {np.percentile(cli, 90):.2f}, max {max(cli):.2f}"] if cli else []),
    ])


def _params(cases: list[Case]) -> str:
    """Per effect parameter: median relative error and 95 % interval coverage, over the verdicts that name
    exactly the withheld effects (an interval holds under its model; a parameter fitted beside a missed
    effect absorbs it)."""
    if not any(c.named_exactly and c.params for c in cases):
        return ""
    lines = ["fitted parameter vs truth (verdicts naming exactly the withheld effects): median |relative error|, "
             "95 % interval coverage"]
    by: dict[str, list[tuple[float, float, float, float]]] = {}
    for c in cases:
        if c.named_exactly:
            for k, v in c.params.items():
                by.setdefault(k, []).append(v)
    covered = []
    for name, vals in sorted(by.items()):
        arr = np.array(vals)
        rel = np.abs(arr[:, 1] - arr[:, 0]) / np.maximum(np.abs(arr[:, 0]), 1e-12)
        inside = (arr[:, 2] <= arr[:, 0]) & (arr[:, 0] <= arr[:, 3])
        covered += list(inside)
        lines.append(f"  {name:32s} {100 * np.median(rel):6.1f} %   coverage {100 * np.mean(inside):5.1f} %  "
                     f"(n = {len(vals)}; Wilson 95 %: {_wilson(list(inside))})")
    if covered:
        lines.append(f"  {'all parameters':32s} {'':8s}   coverage {100 * np.mean(covered):5.1f} %  "
                     f"(n = {len(covered)}; Wilson 95 %: {_wilson(covered)})")
    return "\n".join(lines)


def _sweep(cases: list[Case]) -> str:
    swept = [c for c in cases if c.strength is not None]
    if not swept:
        return ""
    lines = ["strict accuracy as the effect shrinks (strength = fraction of the realistic range's top):",
             f"{'effect':28s}" + "".join(f"{s:>8g}" for s in SWEEP)]
    for t in dict.fromkeys(c.truth for c in swept):
        cells = []
        for s in SWEEP:
            row = [c.right for c in swept if c.truth == t and c.strength == s]
            cells.append(f"{100 * np.mean(row):7.0f}%" if row else f"{'–':>8s}")
        lines.append(f"{t:28s}" + "".join(cells))
    return "\n".join(lines)


def render(cases: list[Case], cli: list[float] | None = None, cores: int = 2) -> str:
    """All tables, main benchmark first, then the magnitude sweep; ``cli`` are timed runs of ``grader diagnose``,
    ``cores`` the cores each diagnosis had."""
    main = [c for c in cases if c.strength is None]
    singles = [c for c in main if "+" not in c.truth]
    pairs = [c for c in main if "+" in c.truth]
    parts = [_headline(singles, pairs, cli or [], cores), _confusion(singles), _pairs(pairs), _params(main)] if main else []
    parts.append(_sweep(cases))
    return "\n\n".join(p for p in parts if p)
