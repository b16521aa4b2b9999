"""MkDocs hook: the CLI reference's option lists come from the parser itself.

A line ``<!-- cli-help: VERB -->`` in a page is replaced by ``grader VERB --help`` as the
installed package prints it. Every verb must appear once in ``reference/cli.md``; a verb
missing there, or a marker naming no verb, stops the build.
"""

from __future__ import annotations

import argparse
import functools
import re

MARKER = re.compile(r"^<!-- cli-help: ([\w-]+) -->$", re.M)
CLI_PAGE = "reference/cli.md"


@functools.cache
def verb_help() -> dict[str, str]:
    """``--help`` text of every verb, wrapped at 96 columns."""
    from grader.cli import build_parser

    parser = build_parser()
    (sub,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    out = {}
    for verb, p in sub.choices.items():
        p.formatter_class = functools.partial(argparse.HelpFormatter, width=96)
        out[verb] = p.format_help().replace("usage: grader", "grader", 1).rstrip()
    return out


def _block(match: re.Match[str]) -> str:
    verb = match.group(1)
    helps = verb_help()
    if verb not in helps:
        raise ValueError(f"<!-- cli-help: {verb} -->: grader has no verb {verb!r}")
    return f"```text\n{helps[verb]}\n```"


def on_page_markdown(markdown: str, page, **_: object) -> str:
    if page.file.src_uri == CLI_PAGE:
        missing = sorted(set(verb_help()) - set(MARKER.findall(markdown)))
        if missing:
            raise ValueError(f"{CLI_PAGE}: no '<!-- cli-help: VERB -->' line for {', '.join(missing)}")
    return MARKER.sub(_block, markdown)
