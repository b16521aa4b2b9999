"""Benchmark: grade 1,000 synthetic submissions with the full rubric and write every output.

    python benchmarks/grading_benchmark.py [--n 1000] [--workers 2] [--unique-designs]

Submissions are built from the grading fixtures (correct, unit slips, known mistakes, error
carried forward, TF forms, designs, hostile answers): each copies a random fixture, perturbs
its numeric answers by up to ±0.5 %, and picks its PD/PI gains from the round numbers students
choose (``--unique-designs``: every group its own gains, the rig simulator's worst case).
The whole ``grader grade`` run is timed as a subprocess (imports, reading, keys, rig simulations,
grading, outputs), against the fixtures' station dataset and its checked-in key
(``reference_solutions/datasets``, ``reference_solutions/keys``); a second run checks that
the outputs are byte-identical.
Target: < 20 s on 2 cores.
"""

from __future__ import annotations

import argparse
import filecmp
import json
import os
import random
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
FIXTURES = ROOT / "submissions_fixtures" / "grading"
NUMBER_ITEMS = ("Kpot", "Kq", "leakage", "Fc", "omega_crit", "beta_over_Vt", "Kce", "Kp_no_overshoot",
                "Kp_25_overshoot", "ramp_ess_P")


def _jitter(value: Any, rng: random.Random) -> Any:
    """Perturb the number in a number-with-unit answer by up to ±0.5 %."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return float(f"{value * (1 + rng.uniform(-0.005, 0.005)):.4g}")
    if isinstance(value, str):
        num, sep, unit = value.partition(" ")
        try:
            return f"{float(num) * (1 + rng.uniform(-0.005, 0.005)):.4g}{sep}{unit}"
        except ValueError:
            return value
    return value


def _designs(rng: random.Random, unique: bool) -> tuple[dict[str, Any], dict[str, Any]]:
    if unique:
        kp, kd = round(rng.uniform(25, 50), 3), round(rng.uniform(0.05, 0.3), 4)
        return ({"Kp": kp, "Kd": kd, "overshoot": "14 %"},
                {"Kp": round(rng.uniform(5, 20), 3), "Ki": round(rng.uniform(5, 80), 3), "ramp_error": "0 in"})
    return ({"Kp": rng.choice([30, 35, 40, 46, 50]), "Kd": rng.choice([0.1, 0.15, 0.2, 0.25, 0.3]), "overshoot": "14 %"},
            {"Kp": rng.choice([5, 10, 15, 20]), "Ki": rng.choice([5, 10, 20, 40, 80]), "ramp_error": "0 in"})


def make_submissions(folder: Path, n: int, *, seed: int = 7, unique_designs: bool = False) -> None:
    """Write ``n`` synthetic submissions into ``folder``."""
    rng = random.Random(seed)
    expected = json.loads((FIXTURES.parent / "grading_expected.json").read_text())
    bases = []
    for p in sorted(FIXTURES.glob("*.json")):
        if not expected.get(p.name, {}).get("valid", False):
            continue  # only readable submissions: every synthetic one must be graded
        try:
            data = json.loads(p.read_text())
        except json.JSONDecodeError:
            continue
        if isinstance(data, dict) and isinstance(data.get("answers"), dict) and data["answers"]:
            bases.append(data)
    for k in range(n):
        base = rng.choice(bases)
        answers = {key: (_jitter(v, rng) if key in NUMBER_ITEMS else v) for key, v in base["answers"].items()}
        if rng.random() < 0.8:
            answers["pd_design"], answers["pi_design"] = _designs(rng, unique_designs)
        sub = {**base, "submission_id": f"bench-{k:04d}", "answers": answers,
               "students": [{"name": f"Student {2 * k + j:04d}", "sis_user_id": f"{900000 + 2 * k + j}",
                             "login_id": f"s{2 * k + j:04d}", "section": f"L0{k % 4 + 1}"} for j in range(2)]}
        (folder / f"bench-{k:04d}.json").write_text(json.dumps(sub, allow_nan=True))


def _child_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run(folder: Path, out: Path, workers: int) -> tuple[float, float]:
    """(wall seconds, CPU seconds of the grader and its workers) of one ``grader grade`` run."""
    t0, c0 = time.perf_counter(), _child_cpu()
    proc = subprocess.run([sys.executable, "-m", "grader.cli", "grade", str(folder), "--out", str(out),
                           "--workers", str(workers), "--no-progress"],
                          capture_output=True, text=True, cwd=ROOT)
    elapsed, cpu = time.perf_counter() - t0, _child_cpu() - c0
    if proc.returncode not in (0, 1):
        raise SystemExit(f"grader grade failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
    return elapsed, cpu


def same_tree(a: Path, b: Path) -> bool:
    files = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file())
    return files == sorted(p.relative_to(b) for p in b.rglob("*") if p.is_file()) and \
        all(filecmp.cmp(a / f, b / f, shallow=False) for f in files)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1000)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--unique-designs", action="store_true")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder, out1, out2 = Path(tmp) / "subs", Path(tmp) / "out1", Path(tmp) / "out2"
        folder.mkdir()
        make_submissions(folder, args.n, unique_designs=args.unique_designs)
        (t1, cpu1), (t2, _) = run(folder, out1, args.workers), run(folder, out2, args.workers)
        report = json.loads((out1 / "report.json").read_text())
        graded = sum(s["valid"] for s in report["submissions"])
        load = os.getloadavg()[0]
        print(f"graded {len(report['submissions'])} submissions ({graded} valid) with {args.workers} workers: "
              f"{t1:.1f} s wall, {cpu1:.1f} s CPU (second run {t2:.1f} s; load average {load:.1f}); "
              f"outputs byte-identical: {same_tree(out1, out2)}")
        if graded != args.n:
            first = next(s for s in report["submissions"] if not s["valid"])
            raise SystemExit(f"{args.n - graded} synthetic submissions were invalid, e.g.: {first['error']}")


if __name__ == "__main__":
    main()
