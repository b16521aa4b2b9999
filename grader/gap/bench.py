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
from grader.stations import Station, load_station
from grader.synth import TRUTH_FILE, make_dataset

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
    make_dataset(station, folder, seed=seed, effects=eff)
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

