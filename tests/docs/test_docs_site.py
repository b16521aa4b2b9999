"""The docs site builds strictly, and the README stays short and points into it."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
README = (ROOT / "README.md").read_text(encoding="utf-8")


def test_mkdocs_build_strict(tmp_path: Path) -> None:
    """Broken links, missing anchors and pages left out of the nav all fail the build."""
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    proc = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "-f", str(ROOT / "mkdocs.yml"), "-d", str(tmp_path / "site")],
        capture_output=True, text=True, env=env, timeout=120,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert (tmp_path / "site" / "reference" / "cli" / "index.html").is_file()


def test_readme_is_short() -> None:
    assert len(README) <= 10_000


def test_readme_test_command_is_what_ci_runs() -> None:
    """.ci/run runs the README's test command, exactly as written there."""
    blocks = re.findall(r"```bash\n(.*?)\n```", README, flags=re.S)
    test_commands = [b for b in blocks if "pytest" in b]
    assert test_commands == ['python -m pip install -e ".[test]" && python -m pytest']
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8").strip().splitlines()[-1]
    assert ci == test_commands[0]


def test_readme_links_into_the_docs_exist() -> None:
    links = re.findall(r"\]\((docs/[^)#]+)", README)
    assert len(links) >= 10
    missing = [link for link in links if not (ROOT / link).is_file()]
    assert missing == []


def _verbs() -> list[str]:
    from grader.cli import build_parser

    parser = build_parser()
    (sub,) = [a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction"]
    return sorted(sub.choices)


def test_readme_tour_has_one_line_per_verb() -> None:
    rows = [line for line in README.splitlines() if line.startswith("| `grader ")]
    first_words = sorted(re.match(r"\| `grader ([\w-]+)", row).group(1) for row in rows)
    assert first_words == _verbs()
