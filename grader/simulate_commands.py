"""CLI verb ``simulate``: write a synthetic lab dataset from the nonlinear rig simulator.

    grader simulate --station default --effect coulomb_friction:Fc=4lbf \\
        --effect sampling_delay:delay=2ms --seed 7 -o data/
    grader simulate --list-effects
"""

from __future__ import annotations

import argparse
from pathlib import Path

from grader.errors import SimulationError
from grader.outpaths import output_folder


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``simulate`` verb."""
    p = subparsers.add_parser(
        "simulate",
        help="write a synthetic lab dataset from the nonlinear rig simulator (effects recorded in truth.json)",
        description="Simulate a station's rig with its own effects (its station file's effects block and "
        "position noise) plus any --effect, and write a complete lab dataset with truth.json beside it. "
        "An --effect replaces the station's effect of the same name; parameters left out take their defaults.",
    )
    p.add_argument("--station", default="default", help="station name or station YAML path (default: default)")
    p.add_argument("--effect", action="append", default=[], metavar="NAME[:PARAM=QUANTITY[,...]]",
                   help="an effect to switch on, e.g. coulomb_friction:Fc=4lbf (repeatable; see --list-effects)")
    p.add_argument("--no-station-effects", action="store_true",
                   help="start from the ideal rig: ignore the station's effects and position noise")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0); same seed, same files")
    p.add_argument("-o", "--out", type=Path, help="output dataset folder")
    p.add_argument("--overwrite", action="store_true", help="write into a folder that already holds a dataset")
    p.add_argument("--list-effects", action="store_true", help="list effect names, parameters and ranges, then exit")
    p.set_defaults(handler=run_simulate)


def effects_table() -> str:
    """The effects, parameters, defaults, admissible and typical ranges as plain text."""
    from grader.model.effects import EFFECTS

    lines = [f"{'effect:param':<34} {'unit':<9} {'default':>8}  {'allowed':<16} {'typical':<14}"]
    for name, spec in EFFECTS.items():
        if not spec.params:
            lines.append(f"{name:<34} {'-':<9} {'-':>8}  {'(no parameter)':<16}")
        for q in spec.params:
            unit = "" if q.unit == "dimensionless" else q.unit
            lines.append(f"{name + ':' + q.name:<34} {unit:<9} {q.default:>8g}  "
                         f"{f'[{q.lo:g}, {q.hi:g}]':<16} {f'[{q.typical[0]:g}, {q.typical[1]:g}]':<14}")
    return "\n".join(lines)


def run_simulate(args: argparse.Namespace) -> int:
    from grader.datasets.load import MANIFEST_NAMES
    from grader.model.effects import EffectSet
    from grader.stations import load_station
    from grader.synth import make_dataset, station_effects

    if args.list_effects:
        print(effects_table())
        return 0
    if args.out is None:
        raise SimulationError("give an output folder with -o/--out")
    if args.seed < 0:
        raise SimulationError(f"--seed must be a non-negative integer, got {args.seed}")
    if args.out.exists() and not args.out.is_dir():
        raise SimulationError(f"{args.out}: is a file, but a folder is expected here; choose another output path")
    if any((args.out / n).exists() for n in MANIFEST_NAMES) and not args.overwrite:
        raise SimulationError(f"{args.out}: already holds a dataset (use --overwrite to replace its files)")
    extra = EffectSet.parse(args.effect)
    output_folder(args.out)  # checked before the station is read and the rig simulated
    station = load_station(args.station)
    base = EffectSet() if args.no_station_effects else station_effects(station)
    effects = base.merged(extra)
    try:
        root = make_dataset(station, args.out, seed=args.seed, effects=effects)
    except OSError as exc:
        raise SimulationError(f"{args.out}: cannot write the dataset ({exc.strerror or exc})") from None
    shown = ", ".join(f"{n}({', '.join(f'{k}={v}' for k, v in ps.items())})" for n, ps in effects.to_quantities().items())
    print(f"wrote {root} (station {station.station}, seed {args.seed}); effects in truth.json: {shown or 'none'}")
    return 0
