"""Core verbs: ``grader key`` (answer key from a dataset) and ``grader demo``."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from rich.console import Console
from rich.table import Table

if TYPE_CHECKING:
    from grader.keys import Key


def key_table(key: Key, *, title: str) -> Table:
    """A readable table of a key's scalar quantities (course units); a not-reachable item
    says so (its reason is in :func:`key_notes`), a value with a note is starred."""
    from grader.units import fmt

    table = Table(title=title)
    for col in ("item", "value", "95 % interval"):
        table.add_column(col, no_wrap=True)
    for name, e in key.quantities.items():
        if not e.reachable:
            table.add_row(f"{name} *", "not reachable", "—")
        elif e.interval is None:
            table.add_row(name, f"per run ({len(e.value)} runs)", "see key file")
        else:
            star = " *" if e.note else ""
            table.add_row(name + star, fmt(e.value, e.unit), f"{e.interval[0]:.4g} … {e.interval[1]:.4g}")
    return table


def key_notes(key: Key) -> list[str]:
    """One line per starred item of :func:`key_table`: why it is not reachable, or its note."""
    return [f"* {name}: {e.reason if not e.reachable else e.note}" for name, e in key.quantities.items()
            if not e.reachable or e.note]


def _key(args: argparse.Namespace) -> int:
    from grader.keys import key_for_dataset, write_key

    key = key_for_dataset(args.dataset)
    out = write_key(key, args.output)
    console = Console()
    console.print(key_table(key, title=f"Answer key for {key.station} ({Path(args.dataset).name})"))
    for line in key_notes(key):
        console.print(line, highlight=False)
    console.print(f"wrote {out}  (inputs sha256 {key.inputs_sha256[:12]}…, grader {key.generated_by['version']})")
    return 0


def _demo(args: argparse.Namespace) -> int:
    from grader.demo import run_demo

    return run_demo(Path(args.out))


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("key", help="build the answer key from a lab dataset folder")
    p.add_argument("dataset", help="lab dataset folder (manifest.json + CSV files)")
    p.add_argument("-o", "--out", "--output", dest="output", default="key.json", help="key file to write (default: key.json)")
    p.set_defaults(handler=_key)
    p = sub.add_parser("demo", help="run the main job end to end on the embedded default station")
    p.add_argument("-o", "--out", default="grader-demo", help="folder for the demo's outputs (default: grader-demo)")
    p.set_defaults(handler=_demo)
