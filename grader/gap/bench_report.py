"""Plain-text tables of the withheld-effect benchmark's results."""

from __future__ import annotations

from collections import Counter

import numpy as np

from grader.gap.bench import SWEEP, Case, expected
from grader.gap.candidates import NONE

ABBREV = {"none": "none", "sampling_delay": "delay", "valve_saturation": "sat", "valve_hysteresis": "hyst",
          "valve_dynamics": "vdyn", "valve_deadband": "dband", "pressure_flow_nonlinearity": "pq",
          "coulomb_friction": "coul", "viscous_friction": "visc", "sensor_quantization": "quant"}


def _confusion(cases: list[Case]) -> str:
    truths = list(dict.fromkeys(c.truth for c in cases))
    verdicts = list(dict.fromkeys([NONE, *[t for t in truths if t != "sensor_quantization"], *[c.verdict for c in cases]]))
    counts = Counter((c.truth, c.verdict) for c in cases)
    corner = "truth \\ verdict"
    head = f"{corner:28s}" + "".join(f"{ABBREV.get(v, v)[:6]:>7s}" for v in verdicts) + "   top-1"
    lines = [head]
    for t in truths:
        row = [c for c in cases if c.truth == t]
        acc = np.mean([c.verdict == expected(t) for c in row])
        note = " (expected: none)" if expected(t) != t else ""
        lines.append(f"{t:28s}" + "".join(f"{counts[(t, v)]:7d}" for v in verdicts) + f"   {100 * acc:5.1f} %{note}")
    return "\n".join(lines)


def _headline(cases: list[Case]) -> str:
    top1 = np.mean([c.verdict == expected(c.truth) for c in cases])
    top2 = np.mean([expected(c.truth) in (c.verdict, c.runner_up) for c in cases])
    strict = np.mean([c.verdict == c.truth for c in cases])
    flagged = np.mean([c.verdict == expected(c.truth) or expected(c.truth) in c.ties for c in cases])
    nones = [c for c in cases if c.truth == NONE]
    fp = np.mean([c.verdict != NONE for c in nones]) if nones else float("nan")
    correct = [c.shrink for c in cases if c.verdict == expected(c.truth) and c.verdict != NONE]
    secs = np.array([c.seconds for c in cases])
    return "\n".join([
        f"datasets: {len(cases)}",
        (f"top-1 accuracy: {100 * top1:.1f} %   top-2 accuracy: {100 * top2:.1f} %   "
         f"(strict top-1, quantisation and viscous friction to be named: {100 * strict:.1f} %)"),
        f"verdict right, or the truth named as indistinguishable from it: {100 * flagged:.1f} %",
        f"false-positive rate on none: {100 * fp:.1f} % ({len(nones)} datasets)",
        (f"median held-out shrink, correct effect verdicts: {100 * np.median(correct):.1f} % ({len(correct)} verdicts)"
         if correct else "median held-out shrink: no correct effect verdicts"),
        (f"seconds per diagnosis: median {np.median(secs):.2f}, 90th percentile {np.percentile(secs, 90):.2f}, "
         f"max {secs.max():.2f}"),
    ])


def _params(cases: list[Case]) -> str:
    lines = ["fitted parameter vs truth (correct verdicts): median |relative error|, 95 % interval coverage"]
    by: dict[str, list[tuple[float, float, float, float]]] = {}
    for c in cases:
        for k, v in c.params.items():
            by.setdefault(f"{c.truth}:{k}", []).append(v)
    for name, vals in by.items():
        arr = np.array(vals)
        rel = np.abs(arr[:, 1] - arr[:, 0]) / np.maximum(np.abs(arr[:, 0]), 1e-12)
        cover = np.mean((arr[:, 2] <= arr[:, 0]) & (arr[:, 0] <= arr[:, 3]))
        lines.append(f"  {name:32s} {100 * np.median(rel):6.1f} %   coverage {100 * cover:5.1f} %  (n = {len(vals)})")
    return "\n".join(lines)


def _sweep(cases: list[Case]) -> str:
    swept = [c for c in cases if c.strength is not None]
    if not swept:
        return ""
    lines = ["accuracy as the effect shrinks (strength = fraction of the realistic range's top):",
             f"{'effect':28s}" + "".join(f"{s:>8g}" for s in SWEEP)]
    for t in dict.fromkeys(c.truth for c in swept):
        cells = []
        for s in SWEEP:
            row = [c for c in swept if c.truth == t and c.strength == s]
            cells.append(f"{100 * np.mean([c.verdict == expected(t) for c in row]):7.0f}%" if row else f"{'–':>8s}")
        lines.append(f"{t:28s}" + "".join(cells))
    return "\n".join(lines)


def render(cases: list[Case]) -> str:
    """All tables, main benchmark first, then the magnitude sweep."""
    main = [c for c in cases if c.strength is None]
    parts = [_headline(main), _confusion(main), _params(main)] if main else []
    parts.append(_sweep(cases))
    return "\n\n".join(p for p in parts if p)
