"""The live preview: how the grader reads what a student typed, as LaTeX for the page's KaTeX.

Expressions go through the same AST whitelist as grading
(:func:`~grader.grading.expressions.parse_expression`, implicit products included) and are
rendered from the checked tree; quantities through the one unit registry. Nothing here
looks at a key: the preview depends on the typed text alone.
"""

from __future__ import annotations

from typing import Any

from grader.errors import GraderError
from grader.grading.items import ITEMS


def _symbol_latex(name: str) -> str:
    """``Kpot`` -> K_{pot}, ``Vt`` -> V_{t}: a multi-letter name shows as one subscripted symbol."""
    greek = {"beta": r"\beta", "zeta": r"\zeta", "omega": r"\omega"}
    if name in greek:
        return greek[name]
    return name if len(name) == 1 else rf"{name[0]}_{{\mathrm{{{name[1:]}}}}}"


def _expression(text: str) -> dict[str, Any]:
    import ast

    import sympy as sp

    from grader.grading.expressions import parse_expression, to_sympy

    expr = parse_expression(text)
    with sp.evaluate(False):  # as typed: 2(s+1) stays 2·(s + 1)
        tree = to_sympy(expr)
    names = {sym: _symbol_latex(sym.name) for sym in tree.free_symbols}
    latex = sp.latex(tree, mul_symbol="dot", order="none", symbol_names=names)
    return {"latex": latex, "read_as": ast.unparse(expr.tree).replace("**", "^")}


def _quantity(item: str, text: str, unit: str | None) -> dict[str, Any]:
    from grader.units import parse_quantity

    q = parse_quantity(text, where=item, default_unit=unit)
    return {"latex": f"{q:~L}" if str(q.units) != "dimensionless" else f"{q.magnitude:g}",
            "read_as": f"{q:~P}"}


def preview(item: str, text: str) -> dict[str, Any]:
    """``{"latex", "read_as"}`` for an answer being typed, or ``{"error"}`` saying why it cannot be read.

    Only expressions and single quantities have a preview; other items return ``{}``.
    """
    spec = ITEMS.get(item)
    if spec is None or spec.kind not in ("expression", "quantity") or not text.strip():
        return {}
    if spec.kind == "quantity" and not any(c.isdigit() for c in text):
        return {}  # words (e.g. "not reachable") are read by the grader, not previewed
    try:
        return _expression(text) if spec.kind == "expression" else _quantity(item, text, spec.unit)
    except GraderError as exc:
        return {"error": str(exc)}
