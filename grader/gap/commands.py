"""Verbs ``grader diagnose`` (sim-to-real diagnosis of a lab dataset) and ``grader bench-gap``
(the withheld-effect benchmark)."""

from __future__ import annotations

import argparse
import gc
import time
from collections.abc import Iterator
from contextlib import contextmanager

from grader.errors import DiagnosisError
from grader.outpaths import output_folder

#: Largest ``bench-gap --valve-null`` [mA]: a valve far off its null is a fault to re-trim, not a rig to diagnose.
MAX_BENCH_NULL = 1.0


def _effects(text: str | None, known: tuple[str, ...] | None = None) -> list[str] | None:
    """Comma-separated effect names, each one of ``known`` (default: the candidate effects)."""
    if text is None:
        return None
    from grader.gap.candidates import physical_effects

    names = [n.strip() for n in text.split(",") if n.strip()]
    known = known or physical_effects()
    bad = [n for n in names if n not in known]
    if bad or not names:
        raise DiagnosisError(f"--effects: unknown candidate(s) {', '.join(bad) or '(none given)'} "
                             f"(known: {', '.join(known)})")
    return names


@contextmanager
def _collector_off() -> Iterator[None]:
    """Python's cyclic garbage collector paused: a diagnosis is one short computation that leaves little
    cyclic garbage, while the collector keeps re-walking every object its imports create (measured on the
    default dataset: about 0.6 s less of 5.5 s, and the same peak memory)."""
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was:
            gc.enable()


def _diagnose(args: argparse.Namespace) -> int:
    from grader.gap.figures import plot_helpers

    t0 = time.perf_counter()
    out = output_folder(args.out)
    # The figure helpers are forked first: they import matplotlib while this process imports scipy.
    with _collector_off(), plot_helpers() as helpers:
        from grader.gap.diagnose import analyse
        from grader.gap.report import write_outputs
        from grader.gap.summary import summary

        analysis = analyse(args.dataset, key=args.key, effects=_effects(args.effects), second=args.second)
        paths = write_outputs(analysis, out, helpers=helpers)
    print(summary(analysis.diagnosis))
    for note in analysis.diagnosis.notes:  # what qualifies the numbers above (also in the report, under them)
        print(f"\nNote: {note}")
    print(f"\nwrote {paths[0]}, {paths[1]} and {len(paths) - 2} plots in {time.perf_counter() - t0:.1f} s")
    return 0


def _bench(args: argparse.Namespace) -> int:
    from grader.gap.bench import TRUTHS, BenchConfig
    from grader.gap.bench_run import run_benchmark

    if not 0.0 <= args.valve_null <= MAX_BENCH_NULL:
        raise DiagnosisError(f"--valve-null must be between 0 and {MAX_BENCH_NULL:g} mA; got {args.valve_null:g}")
    if args.n < 1 or args.pairs < 0 or args.jobs < 1 or args.time_cli < 0:
        raise DiagnosisError(f"--n and --jobs must be at least 1, --pairs and --time-cli at least 0; got {args.n}, "
                             f"{args.jobs}, {args.pairs} and {args.time_cli}")
    cfg = BenchConfig(n=args.n, pairs=args.pairs, seed=args.seed, effects=tuple(_effects(args.effects, TRUTHS) or ()) or None,
                      sweep=args.sweep, workdir=output_folder(args.workdir) if args.workdir else None,
                      friction_test=not args.no_friction_test, jobs=args.jobs, cli_sample=args.time_cli,
                      valve_null=args.valve_null, first_order_spools=args.first_order_spools)
    print(run_benchmark(cfg).text())
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("diagnose", help="locate the sim-to-real gap of a lab dataset and name the effect behind it")
    p.add_argument("dataset", help="lab dataset folder (manifest.json + CSV files)")
    p.add_argument("-o", "--out", default="diagnosis", help="folder for diagnosis.json, report.html and plots (default: diagnosis)")
    p.add_argument("--key", help="answer key whose linear model to use (default: identify it from the dataset)")
    p.add_argument("--effects", help="comma-separated candidate effects to try (default: all)")
    p.add_argument("--second", action="store_true", default=None,
                   help="always try a second effect on top of the verdict (default: when the verdict leaves a residual above the noise)")
    p.set_defaults(handler=_diagnose)
    p = sub.add_parser(
        "bench-gap", help="withheld-effect benchmark of the diagnosis on synthetic datasets",
        description="Generate datasets of random rigs (docs/reference/rig-space.md) on the independent solve_ivp "
                    "simulator, each with one effect, none, or (--pairs) two effects withheld, diagnose them blind "
                    "and score strictly: a verdict is right only when it names exactly the withheld effects, and "
                    "'cannot separate' is a miss. Prints strict top-1 and top-2, the confusion matrix, false "
                    "positives on none, both-named on pairs, median held-out shrink, interval coverage per effect "
                    "and seconds per diagnosis. The issue's setting: --n 25 --pairs 60 --no-friction-test "
                    "(docs/explanation/diagnosis.md, 'Withheld-effect benchmark').")
    p.add_argument("--n", type=int, default=5, help="datasets per effect (default: 5)")
    p.add_argument("--pairs", type=int, default=0, help="datasets with two effects at once (default: 0)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    p.add_argument("--effects", help="comma-separated effects to benchmark (default: all, plus none)")
    p.add_argument("--sweep", action="store_true", help="also measure accuracy as each effect shrinks toward the noise")
    p.add_argument("--workdir", help="keep the generated datasets here (default: a temporary folder); datasets "
                                     "already there from the same seed and plan are diagnosed again, not regenerated")
    p.add_argument("--jobs", type=int, default=1,
                   help="datasets generated and diagnosed at once, each diagnosis on one core (default: 1, "
                        "each diagnosis on two cores)")
    p.add_argument("--time-cli", type=int, default=0, metavar="K",
                   help="also time `grader diagnose` itself (a new process, report included) on K of the datasets")
    p.add_argument("--no-friction-test", action="store_true",
                   help="datasets without the friction test: the diagnosis must find friction from the runs alone")
    p.add_argument("--valve-null", type=float, default=0.0, metavar="MA",
                   help="each dataset's valve rests off its null by a current drawn within ±MA mA in the closed-loop "
                        "runs (not an effect: 'none' stays the right verdict; default: 0, the runs hold no null)")
    p.add_argument("--first-order-spools", action="store_true",
                   help="every withheld spool lag first order, as the benchmark drew them before the afternoon of "
                        "27 November 2026 (default: first or second order, equally often, the second with a damping "
                        "of 0.5 to 1)")
    p.set_defaults(handler=_bench)
