"""The withheld-effect benchmark of the diagnosis (``grader bench-gap``, ``benchmarks/gap_benchmark.py``).

For ``none`` and each canonical effect, N synthetic datasets are made with the rig
simulator (:func:`grader.synth.make_dataset`): the default station with its truth
perturbed within realistic ranges (Kq, Kpot, β/Vt, Kce, position noise), one effect at
a random magnitude from its realistic range, and sensor noise the controller sees. The
runs are the paper's six; the instability run's gain is the first at which the rig's step
response oscillates without decaying (:func:`unstable_gain`). The diagnosis runs blind: ``truth.json`` is taken out of the folder first. Reported: the
confusion matrix, top-1 and top-2 accuracy, the false-positive rate on ``none``, the
median held-out shrink of correct verdicts, seconds per diagnosis and, with ``sweep``,
accuracy as each effect shrinks toward the noise.

Expected verdicts: the effect itself, except ``sensor_quantization`` (measurement noise to the
diagnosis, see :mod:`grader.gap.noise`) and ``viscous_friction``, whose expected verdict is
``none``: the friction data show it, so the students' identification already puts B in the
linear model (and were they missing, B in the closed loop is exactly a larger Kce with β/Vt
and the loop gain re-fitted, so no run could name it). The report gives the strict accuracy,
with these two counted as misses, too.
"""

from __future__ import annotations

import json
import shutil
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from grader.gap.candidates import NONE, physical_effects
from grader.model.effects import EFFECTS, EffectSet
from grader.model.params import Controller, RigParams
from grader.model.rig import simulate_rig_batch
from grader.model.sampled import discrete_critical_gain
from grader.stations import Station, load_station
from grader.synth import INSTABILITY_STEP, TRUTH_FILE, RunPlan, make_dataset

SWEEP = (1.0, 0.5, 0.25, 0.125, 0.0625)
#: Magnitudes are drawn log-uniformly from [top/RANGE_SPAN, top] when the realistic range starts at 0.
RANGE_SPAN = 10.0


#: What a benchmark dataset can withhold.
TRUTHS: tuple[str, ...] = (NONE, *physical_effects(), "sensor_quantization")
#: Effects whose correct verdict is ``none`` (see module docstring).
EXPECT_NONE = ("sensor_quantization", "viscous_friction")


def expected(truth: str) -> str:
    """The verdict a correct diagnosis gives for a dataset with effect ``truth``."""
    return NONE if truth in EXPECT_NONE else truth


def random_station(base: Station, rng: np.random.Generator) -> Station:
    """The default station with Kq, Kpot, β/Vt, Kce and the position noise drawn from realistic ranges."""
    truth = dict(base.truth)
    truth["Kq"] = f"{rng.uniform(0.03, 0.045):.5f} in^3/s/mA"
    truth["Kpot"] = f"{rng.uniform(0.6, 1.5):.4f} V/in"
    truth["beta_over_Vt"] = f"{rng.uniform(1.5e4, 3.0e4):.1f} psi/in^3"
    truth["Kce"] = f"{rng.uniform(4e-4, 1.1e-3):.3e} in^3/s/psi"
    noise = dict(base.noise)
    noise["position"] = f"{np.exp(rng.uniform(np.log(2e-4), np.log(1e-3))):.3e} in"
    return base.model_copy(update={"truth": truth, "noise": noise, "effects": {}})


def effect_params(name: str, rng: np.random.Generator, strength: float | None = None) -> dict[str, float]:
    """A magnitude for ``name``: random over its realistic range, or at ``strength`` × the range's top."""
    out: dict[str, float] = {}
    for p in EFFECTS[name].params:
        if p.name in ("order", "zeta"):
            continue
        lo, hi = p.typical
        if p.name == "bits":
            out[p.name] = float(rng.integers(int(lo), int(hi) + 1))
        elif p.name == "i_max":  # saturation: strength 1 takes the range's bottom, 0 the amplifier's limit
            s = rng.uniform(0.0, 1.0) if strength is None else strength
            out[p.name] = float(50.0 - s * (50.0 - lo))
        elif strength is not None:
            out[p.name] = strength * hi
        else:
            bottom = lo if lo > 0 else hi / RANGE_SPAN
            out[p.name] = float(np.exp(rng.uniform(np.log(bottom), np.log(hi))))
    return out


def _sustained(y: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Runs whose oscillation at the end has not decayed: grown, or a limit cycle of at least 0.02 in."""
    early = np.ptp(y[:, (t >= 0.2) & (t < 0.4)], axis=1)
    late = np.ptp(y[:, t >= t[-1] - 0.2], axis=1)
    return (late > 1.25 * early) | ((late > 0.9 * early) & (late > 0.02))


def unstable_gain(p: RigParams, effects: EffectSet) -> float:
    """The first P gain (on a 0.5 grid) whose step response oscillates without decaying, as students find
    it raising the gain slowly (noise left out). Unlike a pure growth test, a loop that jumps straight into
    a saturated limit cycle counts as unstable."""
    quiet = effects.without("sensor_noise") if "sensor_noise" in effects else effects
    t = np.round(np.arange(0.0, 2.0 + 1e-9, p.sample_time), 9)
    r = np.where(t >= 0.1, INSTABILITY_STEP, 0.0)

    def first(gains: np.ndarray) -> float | None:
        y, _ = simulate_rig_batch(p, [Controller(float(k)) for k in gains], t, r, quiet)
        hit = np.flatnonzero(_sustained(y, t))
        return float(gains[hit[0]]) if hit.size else None

    k_lin = discrete_critical_gain(p)
    step = float(max(1.0, np.ceil(0.05 * k_lin)))
    coarse = first(np.arange(max(0.5, np.floor(0.2 * k_lin)), 3.0 * k_lin + step, step))
    if coarse is None:
        return float(np.ceil(3.0 * k_lin))
    return first(np.arange(max(coarse - step + 0.5, 0.5), coarse, 0.5)) or coarse


def bench_runs(p: RigParams, effects: EffectSet) -> list[RunPlan]:
    """The paper's six runs (volts feedback), the instability run at :func:`unstable_gain`."""
    return [
        RunPlan("step_kp10", "step", Controller(10)),
        RunPlan("step_kp25", "step", Controller(25)),
        RunPlan("step_kp46", "step", Controller(46)),
        RunPlan("instability", "instability", Controller(unstable_gain(p, effects)), amplitude=INSTABILITY_STEP,
                duration=2.0),
        RunPlan("ramp_p", "ramp", Controller(10), amplitude=1.0),
        RunPlan("ramp_pi", "ramp", Controller(10, Ki=20), amplitude=1.0),
    ]


@dataclass(frozen=True)
class Case:
    """One benchmark dataset's outcome."""

    truth: str
    strength: float | None
    verdict: str
    runner_up: str | None
    ties: tuple[str, ...]
    shrink: float
    seconds: float
    params: dict[str, tuple[float, float, float, float]]  # name: (truth, fitted, lo, hi)


@dataclass(frozen=True)
class BenchConfig:
    n: int = 5
    seed: int = 0
    effects: tuple[str, ...] | None = None
    sweep: bool = False
    workdir: Path | None = None


@dataclass
class BenchResult:
    cases: list[Case] = field(default_factory=list)

    def text(self) -> str:
        from grader.gap.bench_report import render

        return render(self.cases)


def _one(station: Station, truth: str, params: dict[str, float], folder: Path, seed: int, strength: float | None) -> Case:
    from grader.gap.diagnose import analyse

    effects = {"sensor_noise": {"sigma": station.noise_values()["position"]}}
    if truth != NONE:
        effects[truth] = params
    eff = EffectSet(effects)
    make_dataset(station, folder, seed=seed, effects=eff, runs=bench_runs(station.params(), eff))
    truth_file = folder.parent / f"{folder.name}.truth.json"  # blind: the truth stays with the benchmark
    (folder / TRUTH_FILE).replace(truth_file)
    data = json.loads(truth_file.read_text(encoding="utf-8"))
    data["station_truth"], data["station_noise"] = station.truth, station.noise
    truth_file.write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")
    t0 = time.perf_counter()
    d = analyse(folder).diagnosis
    seconds = time.perf_counter() - t0
    best = d.candidates[0]
    fitted = {}
    if best.effect == truth:
        for k, v in best.params.items():
            if k in params:
                lo, hi = v.interval or (v.value, v.value)
                fitted[k] = (params[k], v.value, lo, hi)
    return Case(truth, strength, d.verdict.effect, d.verdict.runner_up, tuple(d.verdict.indistinguishable_from),
                best.shrink, seconds, fitted)


def _plan(cfg: BenchConfig) -> list[tuple[str, float | None]]:
    names = list(cfg.effects) if cfg.effects else list(TRUTHS)
    plan: list[tuple[str, float | None]] = [(n, None) for n in names for _ in range(cfg.n)]
    if cfg.sweep:
        swept = [n for n in names if n not in (NONE, "pressure_flow_nonlinearity", "sensor_quantization")]
        plan += [(n, s) for n in swept for s in SWEEP for _ in range(max(1, cfg.n // 2))]
    return plan


def run_benchmark(cfg: BenchConfig, *, progress: bool = True) -> BenchResult:
    """Generate, diagnose blind and collect (see module docstring)."""
    rng = np.random.default_rng(cfg.seed)
    base = load_station("default")
    root = cfg.workdir or Path(tempfile.mkdtemp(prefix="bench-gap-"))
    result = BenchResult()
    try:
        for k, (truth, strength) in enumerate(_plan(cfg)):
            station = random_station(base, rng)
            params = effect_params(truth, rng, strength) if truth != NONE else {}
            case = _one(station, truth, params, root / f"{k:04d}_{truth}", int(rng.integers(2**31)), strength)
            result.cases.append(case)
            if progress:
                mark = "ok " if case.verdict == expected(truth) else "MISS"
                print(f"[{k + 1}] {mark} {truth} {json.dumps(params)} -> {case.verdict} "
                      f"(shrink {case.shrink:.2f}, {case.seconds:.1f} s)", flush=True)
    finally:
        if cfg.workdir is None:
            shutil.rmtree(root, ignore_errors=True)
    return result

