"""Core verbs: ``grader key`` (answer key from a dataset) and ``grader demo``."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from grader.outpaths import output_file, output_folder

if TYPE_CHECKING:  # heavy modules are imported inside the handlers (fast start-up)
    from rich.table import Table

    from grader.keys import Key


def key_table(key: Key, *, title: str) -> Table:
    """A readable table of a key's scalar quantities (course units); a not-reachable or
    not-identifiable item says so (its reason is in :func:`key_notes`), a value with a note is starred."""
    from rich.markup import escape
    from rich.table import Table

    from grader.units import fmt

    table = Table(title=escape(title))
    for col in ("item", "value", "95 % interval"):
        table.add_column(col, no_wrap=True)
    for name, e in key.quantities.items():
        if not e.reachable:
            table.add_row(f"{name} *", e.status.replace("_", " "), "—")
        elif e.interval is None:
            table.add_row(name, f"per run ({len(e.value)} runs)", "see key file")
        else:
            star = " *" if e.note else ""
            table.add_row(name + star, fmt(e.value, e.unit), f"{e.interval[0]:.4g} … {e.interval[1]:.4g}")
    return table


def key_notes(key: Key) -> list[str]:
    """One line per reason or note of the starred items of :func:`key_table` (why an item is not
    reachable or not identifiable, or its note), the items sharing it named together."""
    shared: dict[str, list[str]] = {}
    for name, e in key.quantities.items():
        if not e.reachable or e.note:
            shared.setdefault(str(e.reason if not e.reachable else e.note), []).append(name)
    return [f"* {', '.join(names)}: {why}" for why, names in shared.items()]


def _key(args: argparse.Namespace) -> int:
    from rich.console import Console
    from rich.markup import escape

    from grader.keys import key_for_dataset, write_key

    output_file(args.output, example="key.json")
    key = key_for_dataset(args.dataset)
    out = write_key(key, args.output)
    console = Console()
    console.print(key_table(key, title=f"Answer key for {key.station} ({Path(args.dataset).name})"))
    for line in key_notes(key):
        console.print(escape(line), highlight=False)
    console.print(f"wrote {out}  (inputs sha256 {key.inputs_sha256[:12]}…, grader {key.generated_by['version']})")
    return 0


def _demo(args: argparse.Namespace) -> int:
    from grader.demo import run_demo

    return run_demo(output_folder(args.out))


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("key", help="build the answer key from a lab dataset folder")
    p.add_argument("dataset", help="lab dataset folder (manifest.json + CSV files)")
    p.add_argument("-o", "--out", "--output", dest="output", default="key.json", help="key file to write (default: key.json)")
    p.set_defaults(handler=_key)
    p = sub.add_parser("demo", help="run the main job end to end on the embedded default station")
    p.add_argument("-o", "--out", default="grader-demo", help="folder for the demo's outputs (default: grader-demo)")
    p.set_defaults(handler=_demo)
