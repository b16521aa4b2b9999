"""Any rig: key, grade, check and diagnose random rigs drawn from the realistic space.

Run: ``python benchmarks/anyrig_benchmark.py [--n 200] [--seed 0] [--jobs 2] [--skip-diagnose]``.

Each rig is drawn from the space documented in docs/reference/rig-space.md (Kq, Kpot, β/Vt,
Kce, B, weight, sample time, feedback convention) and simulated with the nonlinear rig
simulator, with position noise, a quantizing ADC and Coulomb friction as on a real bench.
The lab's gains are chosen as a lab instructor would for that rig: the paper's fractions
(10, 25, 46 of a critical gain near 56) of the rig's own critical gain, the instability run
found on the rig. For each rig the benchmark runs, in process, ``grader key``, ``grader grade``
on a fully correct submission built from that key (every item except the two designs, whose
goals are course-specific), ``grader check`` and ``grader diagnose``, and reports the share of
rigs where every verb exits 0, every graded item is correct and the key recovers the truth
within Kpot 1 %, Kq 2 %, β/Vt_model 5 % and Kce_model 5 %, with the worst error of each.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
import sys
import tempfile
import time
import traceback
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from grader.cli import main as grader_main  # noqa: E402
from grader.model import zloop  # noqa: E402
from grader.model.params import Controller  # noqa: E402
from grader.stations import Station, load_station  # noqa: E402
from grader.synth import RunPlan, instability_gain, make_dataset, station_effects  # noqa: E402

BOUNDS = {"Kpot": 0.01, "Kq": 0.02, "beta_over_Vt_model": 0.05, "Kce_model": 0.05}
TRUTH_OF = {"Kpot": "Kpot", "Kq": "Kq", "beta_over_Vt_model": "beta_over_Vt", "Kce_model": "Kce"}
#: the prelab transfer functions (volts convention, the rubric's default): correct on every rig
TF = {
    "closed_loop_tf": "X(s)/R(s) = 4*beta*A*Kp*Kamp*Kpot*Kq / (M*Vt*s^3 + (B*Vt + 4*beta*Kce*M)*s^2 "
                      "+ 4*beta*(A^2 + B*Kce)*s + 4*beta*A*Kp*Kamp*Kpot*Kq)",
    "open_loop_tf": "4*beta*A*Kp*Kamp*Kpot*Kq / (s*(M*Vt*s^2 + (B*Vt + 4*beta*Kce*M)*s + 4*beta*(A^2 + B*Kce)))",
    "char_poly": "s^3 + (B/M + 4*beta*Kce/Vt)*s^2 + 4*beta*(A^2 + B*Kce)/(M*Vt)*s + 4*beta*A*Kp*Kamp*Kpot*Kq/(M*Vt) = 0",
}
ANSWERED = ("Kpot", "Kq", "leakage", "B", "Fc", "omega_crit", "Kp_crit", "beta_over_Vt", "Kce",
            "Kp_no_overshoot", "Kp_25_overshoot", "ramp_ess_P")


def draw_station(base: Station, rng: np.random.Generator, k: int) -> Station:
    """One rig of the realistic space (see the module docstring)."""
    u = rng.uniform
    truth = {**base.truth,
             "Kq": f"{u(0.02, 0.06):.5g} in^3/s/mA", "Kpot": f"{u(0.4, 2.5):.4g} V/in",
             "beta_over_Vt": f"{u(2e4, 8e4):.5g} psi/in^3", "Kce": f"{10 ** u(-4, -3):.4g} in^3/s/psi",
             "B": "0 lbf*s/in" if rng.random() < 0.3 else f"{u(0, 1):.3g} lbf*s/in",
             "leakage": f"{u(0, 0.3):.3g} in^3/s", "null_offset": f"{u(-1, 1):.3g} mA", "pot_offset": f"{u(1, 6):.3g} V"}
    given = base.given.model_copy(update={"weight": f"{u(10, 60):.3g} lbf", "sample_time": f"{u(0.5, 5):.3g} ms"})
    effects = {"coulomb_friction": {"Fc": f"{u(0.3, 3):.3g} lbf"},
               "sensor_quantization": {"bits": str(int(rng.choice([12, 14, 16])))}}
    return base.model_copy(update={"station": f"rig{k:03d}", "feedback": str(rng.choice(["volts", "inches"])),
                                   "truth": truth, "given": given, "effects": effects})


def lab_runs(st: Station) -> list[RunPlan]:
    """The paper's runs at the paper's fractions of this rig's critical gain (its own convention)."""
    p = st.params()
    kc = zloop.critical_gain(p)
    scale = 1.0 if p.feedback == "volts" else p.Kpot
    k_unstable = instability_gain(p, station_effects(st)) * scale

    def g(f: float) -> float:
        return float(f"{f * kc:.3g}")

    return [
        RunPlan("step_kp10", "step", Controller(g(10 / 56))),
        RunPlan("step_kp25", "step", Controller(g(25 / 56))),
        RunPlan("step_kp46", "step", Controller(g(46 / 56))),
        RunPlan("instability", "instability", Controller(k_unstable), amplitude=0.2, duration=2.0),
        RunPlan("ramp_p", "ramp", Controller(g(10 / 56)), amplitude=1.0),
        RunPlan("ramp_pi", "ramp", Controller(g(10 / 56), Ki=g(20 / 56)), amplitude=1.0),
    ]


def correct_submission(key: dict[str, Any], station: str) -> dict[str, Any]:
    """Every item (designs left out) answered with the key's value in the key's unit."""
    q = key["quantities"]
    answers: dict[str, Any] = dict(TF)
    for name in ANSWERED:
        e = q[name]
        if e.get("status", "ok") != "ok":
            answers[name] = e["status"].replace("_", " ")
        else:
            answers[name] = e["value"] if e["unit"] == "dimensionless" else f"{e['value']:.6g} {e['unit']}"
    if q["closed_loop_poles"].get("status", "ok") == "ok":
        answers["closed_loop_poles"] = [{"Kp": r["Kp"], "Ki": r["Ki"], "Kd": r["Kd"],
                                         "poles": [f"{re:.6g}{im:+.6g}j" for re, im in r["poles"]]}
                                        for r in q["closed_loop_poles"]["value"]]
    else:
        answers["closed_loop_poles"] = q["closed_loop_poles"]["status"].replace("_", " ")
    return {"submission_id": f"{station}-correct", "students": [{"name": "A Student"}], "station": station,
            "answers": answers}


@dataclass
class Outcome:
    k: int
    station: str
    feedback: str
    exits: dict[str, int] = field(default_factory=dict)
    errors: dict[str, float] = field(default_factory=dict)
    not_correct: list[str] = field(default_factory=list)
    not_reachable: list[str] = field(default_factory=list)
    not_identifiable: bool = False
    failure: str = ""
    seconds: float = 0.0

    @property
    def keyed_and_graded(self) -> bool:
        return not self.failure and all(v == 0 for v in self.exits.values()) and not self.not_correct

    @property
    def recovered(self) -> bool:
        return self.keyed_and_graded and all(self.errors.get(n, math.inf) <= b for n, b in BOUNDS.items())


def _verb(argv: list[str]) -> int:
    """One grader verb in process, its printing swallowed; a traceback counts as exit 99."""
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        try:
            return int(grader_main(argv) or 0)
        except SystemExit as exc:
            return int(exc.code or 0)
        except Exception:  # noqa: BLE001 - the benchmark records it
            return 99


def one_rig(k: int, seed: int, diagnose: bool) -> Outcome:
    t0 = time.perf_counter()
    st = draw_station(load_station("default"), np.random.default_rng([seed, k]), k)
    out = Outcome(k, st.station, st.feedback)
    try:
        with tempfile.TemporaryDirectory() as tmp:
            root = Path(tmp)
            ds = make_dataset(st, root / "datasets" / st.station, seed=k, runs=lab_runs(st), effects=station_effects(st))
            (root / "keys").mkdir()
            key_file = root / "keys" / f"{st.station}.json"
            out.exits["key"] = _verb(["key", str(ds), "-o", str(key_file)])
            key = json.loads(key_file.read_text())
            truth = st.params()
            out.errors = {n: abs(key["quantities"][n]["value"] / getattr(truth, TRUTH_OF[n]) - 1) for n in BOUNDS
                          if key["quantities"][n]["value"] is not None}
            out.not_reachable = [n for n, e in key["quantities"].items() if e.get("status") == "not_reachable"]
            out.not_identifiable = key["quantities"]["Kce"].get("status") == "not_identifiable"
            sub = root / "sub.json"
            sub.write_text(json.dumps(correct_submission(key, st.station)))
            where = ["--datasets", str(root / "datasets"), "--keys", str(root / "keys")]
            out.exits["grade"] = _verb(["grade", "--workers", "1", "--no-progress", *where, "-o", str(root / "g"), str(sub)])
            report = json.loads((root / "g" / "report.json").read_text())
            out.not_correct = [f"{i['item']}:{i['status']}" for s in report["submissions"] for i in s["items"]
                               if i["item"] in {*ANSWERED, *TF, "closed_loop_poles"} and i["status"] != "correct"]
            out.exits["check"] = _verb(["check", *where, str(sub)])
            if diagnose:
                out.exits["diagnose"] = _verb(["diagnose", str(ds), "--key", str(key_file), "-o", str(root / "d")])
    except Exception:  # noqa: BLE001
        out.failure = traceback.format_exc(limit=3).strip().splitlines()[-1]
    out.seconds = time.perf_counter() - t0
    return out


def report(outcomes: list[Outcome], wall: float) -> str:
    n = len(outcomes)
    ok = sum(o.keyed_and_graded for o in outcomes)
    rec = sum(o.recovered for o in outcomes)
    lines = [f"{n} rigs in {wall:.0f} s: {ok}/{n} ({100 * ok / n:.1f} %) keyed, graded, checked"
             + ("" if "diagnose" not in outcomes[0].exits else ", diagnosed") + " with every verb exiting 0 "
             f"and every answered item correct; {rec}/{n} ({100 * rec / n:.1f} %) also within the recovery bounds"]
    for name, bound in BOUNDS.items():
        errs = [(o.errors[name], o.station) for o in outcomes if name in o.errors]
        if errs:
            worst, where = max(errs)
            inside = sum(e <= bound for e, _ in errs)
            lines.append(f"  {name:<20} bound {100 * bound:g} %: {inside}/{len(errs)} within; worst {100 * worst:.2f} % ({where})")
    nr: dict[str, int] = {}
    for o in outcomes:
        for item in o.not_reachable:
            nr[item] = nr.get(item, 0) + 1
    lines.append("  not reachable in keys: " + (", ".join(f"{k} {v}" for k, v in sorted(nr.items())) or "none"))
    ni = [o.station for o in outcomes if o.not_identifiable]
    lines.append(f"  keys with β/Vt and Kce not identifiable (no critical oscillation in the instability run): {len(ni)}"
                 + (f" ({', '.join(ni)})" if ni else ""))
    for o in outcomes:
        if not o.recovered:
            lines.append(f"  FAIL {o.station} ({o.feedback}): exits {o.exits} {o.failure} "
                         f"{' '.join(o.not_correct)} errors " + " ".join(f"{k}={100 * v:.2f}%" for k, v in o.errors.items()))
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=200, help="number of rigs (default 200)")
    ap.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    ap.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")
    ap.add_argument("--skip-diagnose", action="store_true", help="do not run grader diagnose (the slow verb)")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        outcomes = list(pool.map(one_rig, range(args.n), [args.seed] * args.n, [not args.skip_diagnose] * args.n))
    print(report(outcomes, time.perf_counter() - t0))
    return 0 if all(o.recovered for o in outcomes) else 1


if __name__ == "__main__":
    sys.exit(main())
