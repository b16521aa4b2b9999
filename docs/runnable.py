"""Runnable commands in the docs: every ```console block, executed against the embedded data.

A ```console block holds ``$ grader ...`` lines, each followed by the output the text states
(none, or some lines). A command passes when it exits with 0 (or with N when the line ends in
``# exit N``) and every stated output line appears in its output, in order, whitespace
collapsed and table borders ignored (a wrapped table cell reads as one line), ``…``
standing for any text. The commands of one page run in order in one working
folder holding copies of ``reference_solutions/``, ``rubrics/`` and ``submissions_fixtures/``,
in this process through :func:`grader.cli.main` (one import of the package for all of them).
Plain ``` blocks are synopses and are not run.
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import shlex
import shutil
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
FENCE = re.compile(r"^```console\n(.*?)^```", re.M | re.S)
EXIT = re.compile(r"\s+#\s*exit\s+(\d+)\s*$")
COPIED = ("reference_solutions", "rubrics", "submissions_fixtures")


@dataclass
class Command:
    """One ``$ grader ...`` line of a page and the output stated under it."""

    page: str
    line: int
    text: str
    exit_code: int = 0
    expected: list[str] = field(default_factory=list)

    @property
    def argv(self) -> list[str]:
        return shlex.split(self.text)


def page_commands(page: Path) -> list[Command]:
    """The runnable commands of one Markdown page, in order."""
    text = page.read_text(encoding="utf-8")
    name = page.relative_to(DOCS).as_posix()
    out: list[Command] = []
    for block in FENCE.finditer(text):
        first = text.count("\n", 0, block.start(1)) + 1
        for offset, line in enumerate(block.group(1).splitlines()):
            if line.startswith("$ "):
                cmd, code = line[2:], 0
                if m := EXIT.search(cmd):
                    cmd, code = cmd[: m.start()], int(m.group(1))
                out.append(Command(name, first + offset, cmd.strip(), code))
            elif line.strip():
                if not out or out[-1].line < first:
                    raise ValueError(f"{name}:{first + offset}: output before any '$ ' command in a console block")
                out[-1].expected.append(line.strip())
    return out


def pages_with_commands() -> list[Path]:
    return sorted(p for p in DOCS.rglob("*.md") if FENCE.search(p.read_text(encoding="utf-8")))


def make_workspace(folder: Path) -> Path:
    """A working folder with copies of the embedded data (commands may write into it)."""
    folder.mkdir(parents=True, exist_ok=True)
    for name in COPIED:
        shutil.copytree(ROOT / name, folder / name, dirs_exist_ok=True)
    return folder


@contextlib.contextmanager
def _inside(folder: Path) -> Iterator[None]:
    old, columns = Path.cwd(), os.environ.get("COLUMNS")
    os.chdir(folder)
    os.environ["COLUMNS"] = "120"
    try:
        yield
    finally:
        os.chdir(old)
        if columns is None:
            os.environ.pop("COLUMNS", None)
        else:
            os.environ["COLUMNS"] = columns


def run(command: Command, folder: Path) -> tuple[int, str]:
    """Run one command in ``folder``; returns its exit code and its stdout and stderr together."""
    from grader.cli import main

    argv = command.argv
    if argv[0] != "grader":
        raise ValueError(f"{command.page}:{command.line}: runnable commands start with 'grader', not {argv[0]!r}")
    buffer = io.StringIO()
    with _inside(folder), contextlib.redirect_stdout(buffer), contextlib.redirect_stderr(buffer):
        try:
            code = main(argv[1:])
        except SystemExit as exc:  # argparse errors and --help
            code = exc.code if isinstance(exc.code, int) else 1
    return code, buffer.getvalue()


BOX = re.compile("[\u2500-\u257f]")


def _squash(text: str) -> str:
    """Whitespace collapsed and table borders dropped, so wrapped table cells read as one line."""
    return " ".join(BOX.sub(" ", text).split())


def problems(command: Command, code: int, output: str) -> list[str]:
    """What differs from what the page states; empty when the command passes."""
    where = f"{command.page}:{command.line}: $ {command.text}"
    found: list[str] = []
    if code != command.exit_code:
        found.append(f"{where}: exit code {code}, the page implies {command.exit_code}")
    text, pos = _squash(output), 0
    for line in command.expected:
        for part in filter(None, (_squash(p) for p in line.split("…"))):
            at = text.find(part, pos)
            if at < 0:
                found.append(f"{where}: output lacks {part!r}")
                break
            pos = at + len(part)
    return found
