"""Plain sentences saying whether the survey supports "lab X was rated highest for S".

The claim is made only when (1) one lab has the highest mean, (2) the Friedman
test across labs is significant (when there are three or more labs), and (3) the
Holm-corrected Wilcoxon test of that lab against every other lab is significant,
in the claimed direction.
Otherwise the sentence says the data do not support it, and why.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from grader.assess.stats import FriedmanResult, PairResult

SIGNIFICANCE = 0.05


def format_p(p: float) -> str:
    """A p-value as text: '<0.001', else 3 significant digits (more if rounding would cross 0.05)."""
    if p < 0.001:
        return "<0.001"
    text = f"{p:.3g}"
    if (float(text) < SIGNIFICANCE) != (p < SIGNIFICANCE):
        text = f"{p:.5f}"
    return text


def fmt_p(p: float | None) -> str:
    """'p < 0.001', 'p = 0.0123' or 'p not available', for sentences."""
    if p is None:
        return "p not available"
    text = format_p(p)
    return "p < 0.001" if text.startswith("<") else f"p = {text}"


def _against(top: str, other: str, pairs: Sequence[PairResult]) -> tuple[PairResult, float]:
    """The pair test of ``top`` vs ``other`` and the paired mean difference top − other."""
    pair = next(p for p in pairs if {p.a, p.b} == {top, other})
    diff = pair.mean_diff or 0.0
    return pair, diff if pair.a == top else -diff


def highest_claim(
    statement_label: str,
    means: Mapping[str, float | None],
    friedman: FriedmanResult | None,
    pairs: Sequence[PairResult],
    names: Mapping[str, str],
) -> tuple[str | None, bool, str]:
    """``(highest lab id or None, claim supported?, sentence)``.

    With only two labs there is no omnibus test: the one pairwise test decides.
    """
    rated = {lab: m for lab, m in means.items() if m is not None}
    if len(rated) < 2:
        return None, False, f'Too few labs were rated on "{statement_label}" to compare them.'
    best = max(rated.values())
    tops = [lab for lab, m in rated.items() if abs(m - best) < 1e-9]
    if len(tops) > 1:
        tied = " and ".join(names[lab] for lab in tops)
        return None, False, f'No lab was rated highest on "{statement_label}": {tied} tie at mean {best:.2f}.'
    top = tops[0]
    head = f'the {names[top]} lab was rated highest on "{statement_label}"'
    lead = f"The data do not support the claim that {head}: it has the highest mean ({best:.2f})"
    omnibus = ""
    if len(means) >= 3:
        if friedman is None:
            return top, False, f"{lead}, but too few students rated every lab to test it."
        omnibus = (
            f"Friedman χ²({friedman.df}) = {friedman.chi2:.2f}, {fmt_p(friedman.p)}, "
            f"Kendall's W = {friedman.kendall_w:.2f}, n = {friedman.n} students who rated every lab"
        )
        if friedman.p >= SIGNIFICANCE:
            return top, False, f"{lead}, but the labs do not differ significantly ({omnibus})."
    failures = _failed_pairs(top, [lab for lab in rated if lab != top], pairs, names)
    if failures:
        differ = f" and the labs differ ({omnibus})" if omnibus else ""
        return top, False, f"{lead}{differ}, but {failures}."
    worst = max(_against(top, other, pairs)[0].p_holm or 0.0 for other in rated if other != top)
    largest = "all p < 0.001" if worst < 0.001 else f"largest Holm {fmt_p(worst)}"
    return top, True, (
        f"The data support the claim that {head}: mean {best:.2f}; {omnibus + '; ' if omnibus else ''}"
        f"its Wilcoxon signed-rank test against every other lab is significant after Holm correction ({largest})."
    )


def _failed_pairs(top: str, others: Sequence[str], pairs: Sequence[PairResult], names: Mapping[str, str]) -> str:
    """Describe the pairwise tests that do not back the claim ('' if none)."""
    reasons = []
    for other in others:
        pair, diff = _against(top, other, pairs)
        if pair.p_holm is None:
            reasons.append(f"no students rated both it and {names[other]}")
        elif pair.p_holm >= SIGNIFICANCE:
            reasons.append(
                f"its difference from {names[other]} is not significant after Holm correction "
                f"({fmt_p(pair.p_holm)}, n = {pair.n} paired)"
            )
        elif diff <= 0:
            reasons.append(f"students who rated both rated {names[other]} higher (n = {pair.n})")
    return "; ".join(reasons)
