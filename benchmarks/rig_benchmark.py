"""Rig engine speed against scipy's solve_ivp at equal accuracy.

Run: ``python benchmarks/rig_benchmark.py`` (the compiled engine's cache is warmed first).
For a 1.5 s step run at 1 kHz control (Kp = 25, default station) and three effect sets
(none, the station's Coulomb friction, all deterministic effects), it prints:

* the accuracy of the engine (default substeps) against a tight event-located DOP853
  reference (rtol 1e-11);
* the loosest solve_ivp (RK45, per hold interval, stick-slip events) tolerance that is at
  least as accurate, and its time per run (if none down to rtol 1e-10 is, the tightest:
  the ratio is then a lower bound); and the cheapest solve_ivp (rtol 1e-3) for scale;
* runs/s of the engine for one run and for a batch of 1,000 runs with parameters
  varied across the batch, and the ratios to solve_ivp;
* the wall time of ``grader diagnose`` on the default dataset (median of five new processes,
  identified from the dataset and with ``--key``; ``--skip-diagnose`` leaves it out).
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from grader.model.effects import EffectSet
from grader.model.params import Controller
from grader.model.rig import simulate_rig, simulate_rig_batch
from grader.model.rig_ivp import simulate_rig_ivp
from grader.stations import load_station

MODELS = {
    "no effect": [],
    "station (Coulomb 1.2 lbf)": ["coulomb_friction:Fc=1.2lbf"],
    "all deterministic effects": [
        "coulomb_friction:Fc=2lbf", "viscous_friction:B=0.2lbf*s/in", "valve_saturation:i_max=40mA",
        "valve_deadband:width=0.5mA", "valve_hysteresis:width=0.5mA", "pressure_flow_nonlinearity",
        "sampling_delay:delay=1.5ms", "valve_dynamics:tau=1.5ms",
    ],
}
BATCH = 1000


def best_time(fn, repeats: int = 3) -> float:
    """Best CPU time of this process [s] (wall time means little on a shared machine)."""
    best = np.inf
    for _ in range(repeats):
        t0 = time.process_time()
        fn()
        best = min(best, time.process_time() - t0)
    return best


def batch_effects(effects: EffectSet, rng: np.random.Generator) -> list[EffectSet]:
    """``effects`` with its Coulomb friction (if on) drawn from the typical range, one set per run."""
    if "coulomb_friction" not in effects:
        return [effects] * BATCH
    fcs = rng.uniform(0.2, 8.0, BATCH)
    return [effects.merged(EffectSet({"coulomb_friction": {"Fc": float(fc)}})) for fc in fcs]


def bench(name: str, specs: list[str]) -> None:
    station = load_station("default")
    p, c = station.params(), Controller(25)
    t = np.round(np.arange(0.0, 1.5 + 1e-9, p.sample_time), 9)
    r = np.where(t >= 0.1, 0.2, 0.0)
    effects = EffectSet.parse(specs)
    ref, _ = simulate_rig_ivp(p, c, r, effects, rtol=1e-11, atol=1e-13, method="DOP853")
    y, _ = simulate_rig(p, c, t, r, effects)
    err = float(np.abs(y - ref).max())
    t_one = best_time(lambda: simulate_rig(p, c, t, r, effects), repeats=20)
    ivp_tol, ivp_err, t_ivp, bound = None, np.inf, np.inf, ""
    for rtol in (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10):
        y_ivp, _ = simulate_rig_ivp(p, c, r, effects, rtol=rtol, atol=rtol * 1e-3)
        ivp_tol, ivp_err = rtol, float(np.abs(y_ivp - ref).max())
        if ivp_err <= err or rtol == 1e-10:
            bound = "" if ivp_err <= err else " (never as accurate: ratios are lower bounds)"
            t_ivp = best_time(lambda tol=rtol: simulate_rig_ivp(p, c, r, effects, rtol=tol, atol=tol * 1e-3), repeats=2)
            break
    t_cheap = best_time(lambda: simulate_rig_ivp(p, c, r, effects, rtol=1e-3, atol=1e-6), repeats=2)
    rng = np.random.default_rng(0)
    params = [p.with_(Kce=p.Kce * f) for f in rng.uniform(0.8, 1.2, BATCH)]
    sets = batch_effects(effects, rng)
    t_batch = best_time(lambda: simulate_rig_batch(params, c, t, r, sets), repeats=2)
    print(f"\n== {name}: {', '.join(specs)}")
    print(f"  accuracy vs DOP853 reference:   engine {err:.2e} in;  solve_ivp RK45 rtol={ivp_tol:g}: {ivp_err:.2e} in"
          f"{bound}")
    print(f"  solve_ivp (equal accuracy):     {t_ivp * 1e3:8.1f} ms/run  = {1 / t_ivp:8.1f} runs/s")
    print(f"  solve_ivp (rtol 1e-3):          {t_cheap * 1e3:8.1f} ms/run  = {1 / t_cheap:8.1f} runs/s"
          f"   engine one run: {t_cheap / t_one:6.1f}x faster")
    print(f"  engine, one run:                   {t_one * 1e3:8.1f} ms/run  = {1 / t_one:8.1f} runs/s"
          f"   ratio {t_ivp / t_one:6.1f}x")
    print(f"  engine, batch of {BATCH} (Kce, Fc varied): {t_batch:6.2f} s        = {BATCH / t_batch:8.1f} runs/s"
          f"   ratio {t_ivp * BATCH / t_batch:6.1f}x")


def diagnose_times(repeats: int = 5) -> None:
    """Wall time of ``grader diagnose`` on the default dataset, each a new process as a user runs it."""
    root = Path(__file__).resolve().parents[1] / "reference_solutions"
    dataset, key = root / "datasets" / "default", root / "keys" / "default.json"
    script = Path(sys.executable).with_name("grader")  # the console script, as users run it
    cmd = [str(script)] if script.exists() else [sys.executable, "-m", "grader.cli"]
    print(f"grader diagnose on the default dataset, wall time of a new process, median of {repeats}:")
    with tempfile.TemporaryDirectory() as tmp:
        for label, extra in (("identified from the dataset", []), ("with --key", ["--key", str(key)])):
            times = []
            for _ in range(repeats):
                t0 = time.perf_counter()
                subprocess.run([*cmd, "diagnose", str(dataset), "-o", tmp, *extra],
                               check=True, stdout=subprocess.DEVNULL)
                times.append(time.perf_counter() - t0)
            print(f"  {label:28s} {statistics.median(times):5.2f} s  (min {min(times):.2f}, max {max(times):.2f})")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--skip-diagnose", action="store_true", help="do not time grader diagnose")
    args = ap.parse_args()
    print("Rig engine benchmark: 1.5 s step run, 1 kHz control, Kp = 25, default station; one process, CPU times")
    warm = load_station("default").params()
    simulate_rig(warm, Controller(25), np.arange(0.0, 0.01, 0.001), np.zeros(10))  # load the compiled engine
    for name, specs in MODELS.items():
        bench(name, specs)
    if not args.skip_diagnose:
        diagnose_times()


if __name__ == "__main__":
    main()
