"""Running the withheld-effect benchmark (:mod:`grader.gap.bench`): datasets generated and diagnosed blind,
one at a time or ``jobs`` at once, and ``grader diagnose`` itself timed on a sample.

Each planned dataset lands in the work folder as ``NNNN_<effects>`` with its truth beside it. A dataset
already there (same seed and plan: the truth file matches) is diagnosed again, not generated again, so
a change to the diagnosis can be measured on the same data. With ``jobs`` > 1 each diagnosis runs on
one core (the benchmark's workers take the cores), and the reported seconds are one core's.
"""

from __future__ import annotations

import json
import multiprocessing as mp
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from grader.gap.bench import ERROR, GENERATOR, BenchConfig, BenchResult, Case, coverage, effect_params, \
    finest_board, make_case_dataset, plan, random_station, step_demand
from grader.gap.candidates import NONE
from grader.gap.schema import Verdict
from grader.gap.summary import combination
from grader.model.effects import EffectSet
from grader.stations import Station, load_station

@dataclass(frozen=True)
class Task:
    """One planned dataset: where it goes, what it withholds and how it is drawn."""

    folder: Path
    label: str
    station: Station
    truth: EffectSet
    seed: int
    strength: float | None
    friction_test: bool
    null: float = 0.0  # [mA] the valve's null in the runs


def tasks(cfg: BenchConfig, root: Path) -> list[Task]:
    """Every planned dataset, drawn in order from the seed (the same plan whatever is reused)."""
    rng = np.random.default_rng(cfg.seed)
    nulls = np.random.default_rng([cfg.seed, 1])  # apart: the same rigs and effects with and without a null
    forms = None if cfg.first_order_spools else np.random.default_rng([cfg.seed, 2])  # apart: a spool's form
    base = load_station("default")
    out = []
    for k, (names, strength) in enumerate(plan(cfg, rng)):
        station = random_station(base, rng)
        demand = step_demand(station)
        finest = finest_board(station) if "sensor_quantization" in names else None
        truth = EffectSet({n: effect_params(n, rng, strength, demand, finest, forms) for n in names if n != NONE})
        label = "+".join(names)
        null = float(nulls.uniform(-cfg.valve_null, cfg.valve_null)) if cfg.valve_null else 0.0
        out.append(Task(root / f"{k:04d}_{label}", label, station, truth, int(rng.integers(2**31)), strength,
                        cfg.friction_test, null))
    return out


def _reusable(task: Task) -> bool:
    """Whether the task's dataset is already in the work folder, made from the same draw by this generator."""
    truth_file = task.folder.parent / f"{task.folder.name}.truth.json"
    if not (task.folder / "manifest.json").is_file() or not truth_file.is_file():
        return False
    try:
        kept = json.loads(truth_file.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    kept_truth = EffectSet.from_quantities(kept.get("effects")).without("sensor_noise")
    return kept.get("generator") == GENERATOR and kept.get("station") == task.station.model_dump(mode="json") and \
        kept_truth.to_quantities() == task.truth.to_quantities() and \
        kept.get("valve_null") == (f"{task.null!r} mA" if task.null else None)


def run_task(task: Task, parallel: bool = True) -> Case:
    """Generate (unless reusable) and diagnose one dataset; a diagnosis that fails is a case whose verdict is
    ``error`` (a miss, counted apart), so that one dataset never stops the benchmark."""
    from grader.gap.diagnose import analyse

    if not _reusable(task):
        shutil.rmtree(task.folder, ignore_errors=True)
        make_case_dataset(task.station, task.truth, task.folder, task.seed, friction_test=task.friction_test,
                          null=task.null)
    t0 = time.perf_counter()
    try:
        d = analyse(task.folder, parallel=parallel).diagnosis
    except Exception as exc:  # noqa: BLE001 - any failure is the benchmark's finding, not its end
        print(f"{task.folder.name}: the diagnosis failed: {type(exc).__name__}: {exc}", file=sys.stderr, flush=True)
        return Case(task.label, task.strength, ERROR, None, None, (), 0.0, time.perf_counter() - t0, {})
    seconds = time.perf_counter() - t0
    named = combination(d) or d.candidates[0]  # the model with every effect named from the runs, as the summary says
    return Case(task.label, task.strength, d.verdict.effect, d.verdict.second_effect, d.verdict.runner_up,
                _ties(d.verdict), named.shrink, seconds, coverage(d, task.truth))


def _ties(v: Verdict) -> tuple[str, ...]:
    """The lookalikes the verdict and its second effect could not be told from, but those it names itself (a
    Coulomb verdict not told from the deadband it names as its second effect names the same two)."""
    named = {v.effect, v.second_effect}
    return tuple(e for e in [*v.indistinguishable_from, *v.second_indistinguishable_from] if e not in named)


def _one_core(task: Task) -> Case:
    return run_task(task, parallel=False)


def _cases(todo: list[Task], jobs: int) -> Iterator[Case]:
    """Each task's case, in order; with ``jobs`` > 1 from a pool of forked processes. Only a run stopped early
    (Ctrl-C) drops the pool's queue and shuts it down without waiting: on Python 3.11 that races the pool's
    manager thread closing its wake-up pipe, and at exit the interpreter then wrote to the closed pipe (an
    ``OSError: Bad file descriptor`` traceback after the tables), so a finished run shuts the pool down waiting."""
    if jobs <= 1:
        yield from (run_task(t) for t in todo)
        return
    with ProcessPoolExecutor(jobs, mp_context=mp.get_context("fork" if "fork" in mp.get_all_start_methods()
                                                            else "spawn")) as ex:
        try:
            yield from ex.map(_one_core, todo)
        except BaseException:  # Ctrl-C or the caller stopping early: drop what is queued
            ex.shutdown(wait=False, cancel_futures=True)
            raise


def time_cli(folders: list[Path]) -> list[float]:
    """Wall seconds of ``grader diagnose`` (a new process, report included) on each folder where it succeeds;
    a failure is reported on stderr with the command's last line and left out."""
    out = []
    with tempfile.TemporaryDirectory(prefix="bench-cli-") as tmp:
        for k, folder in enumerate(folders):
            t0 = time.perf_counter()
            done = subprocess.run([sys.executable, "-m", "grader.cli", "diagnose", str(folder), "-o", f"{tmp}/{k}"],
                                  capture_output=True, text=True)
            if done.returncode != 0:
                last = (done.stderr.strip().splitlines() or ["(no message)"])[-1]
                print(f"{folder.name}: grader diagnose exited {done.returncode}: {last}", file=sys.stderr, flush=True)
                continue
            out.append(time.perf_counter() - t0)
    return out


def run_benchmark(cfg: BenchConfig, *, progress: bool = True) -> BenchResult:
    """Generate, diagnose blind and collect (see module docstring); Ctrl-C keeps the datasets done so far."""
    root = cfg.workdir or Path(tempfile.mkdtemp(prefix="bench-gap-"))
    result = BenchResult(cores=2 if cfg.jobs <= 1 else 1)
    todo = tasks(cfg, root)
    try:
        for k, (task, case) in enumerate(zip(todo, _cases(todo, cfg.jobs))):
            result.cases.append(case)
            if progress:
                print(f"[{k + 1}] {'ok ' if case.right else 'MISS'} {task.label} {json.dumps(task.truth.to_quantities())}"
                      f" -> {'+'.join(case.named)}{''.join(f' ~{t}' for t in case.ties)} (shrink {case.shrink:.2f}, {case.seconds:.1f} s)", flush=True)
        if cfg.cli_sample > 0:
            pick = np.unique(np.linspace(0, len(todo) - 1, min(cfg.cli_sample, len(todo))).round().astype(int))
            result.cli_seconds = time_cli([todo[i].folder for i in pick])
            if progress:
                print(f"grader diagnose on {len(pick)} datasets: median {statistics.median(result.cli_seconds):.2f} s",
                      flush=True)
    except KeyboardInterrupt:  # Ctrl-C: the tables of the datasets done so far
        print(f"interrupted after {len(result.cases)} datasets", flush=True)
    finally:
        if cfg.workdir is None:
            shutil.rmtree(root, ignore_errors=True)
    return result
