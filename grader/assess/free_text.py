"""The free-text "most useful lab, and why" answers: which lab each names, and the quotes.

A lab is named when one of its ``mentions`` appears as whole words (case,
hyphens and punctuation ignored). An answer may name several labs. Quotes are
sorted (by first lab named, then text) so that their order reveals nothing
about who wrote them; identical answers are quoted once with their count, and
e-mail addresses are removed.
"""

from __future__ import annotations

import re
from collections import Counter
from collections.abc import Sequence

from grader.assess.mapping import Lab
from grader.assess.schemas import Mention, MostUseful, Quote

_EMAIL = re.compile(r"[\w.+-]+@[\w-]+(?:\.[\w-]+)+")
_NON_WORD = re.compile(r"[^\w]+")


def _words(text: str) -> str:
    return " " + _NON_WORD.sub(" ", text.casefold()).strip() + " "


def labs_named(answer: str, labs: Sequence[Lab]) -> list[str]:
    """Ids of the labs an answer names, in mapping order."""
    words = _words(answer)
    return [lab.id for lab in labs if any(_words(m) in words for m in (*lab.mentions, lab.name))]


def redact(text: str) -> str:
    """Remove e-mail addresses from a quoted answer."""
    return _EMAIL.sub("[e-mail removed]", text)


def most_useful(answers: Sequence[str], labs: Sequence[Lab]) -> MostUseful:
    """Tally the labs named in the answers and quote every distinct non-blank answer."""
    given = [" ".join(a.split()) for a in answers if a.strip()]
    named = [labs_named(a, labs) for a in given]
    counts = Counter(redact(text) for text in given)
    order = {lab.id: i for i, lab in enumerate(labs)}
    quotes = sorted(
        (Quote(labs=labs_named(text, labs), text=text, count=n) for text, n in counts.items()),
        key=lambda q: (order[q.labs[0]] if q.labs else len(labs), q.text.casefold(), q.text),
    )
    tally = [
        Mention(
            lab=lab.id,
            lab_name=lab.name,
            count=sum(lab.id in ids for ids in named),
            pct=100.0 * sum(lab.id in ids for ids in named) / len(given) if given else None,
        )
        for lab in labs
    ]
    return MostUseful(
        n_answers=len(given),
        n_blank=len(answers) - len(given),
        no_lab_named=sum(not ids for ids in named),
        tally=tally,
        quotes=quotes,
    )
