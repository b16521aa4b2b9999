"""Transfer-function answers: reference forms, exact equivalence, and what differs.

References come from :func:`grader.model.symbolic.reduce_loop` (P control) in the
rubric's feedback convention. Equivalence is exact: two rational functions are equal
iff ``a.num·b.den == b.num·a.den`` as polynomials over QQ. A characteristic polynomial
is accepted up to any factor free of ``s``. When an answer is wrong, the monic
characteristic polynomials are compared coefficient by coefficient.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Literal

import sympy as sp
from sympy.polys.rings import PolyElement

from grader.grading.expressions import GENS, RatFunc, sympy_to_ratfunc
from grader.model.params import Feedback
from grader.model.symbolic import COURSE_SYMBOLS, reduce_loop

Form = Literal["closed_loop_tf", "open_loop_tf", "char_poly"]
FORMS: tuple[str, ...] = ("closed_loop_tf", "open_loop_tf", "char_poly")
_S = GENS["s"]
_OTHER: dict[str, Feedback] = {"volts": "inches", "inches": "volts"}
_SYM = COURSE_SYMBOLS


def _loop_forms(feedback: Feedback) -> dict[str, sp.Expr]:
    loop = reduce_loop(feedback, "P")
    return {"closed_loop_tf": loop.closed_loop, "open_loop_tf": loop.open_loop, "char_poly": loop.char_poly.as_expr()}


def _transformed(form: str, feedback: Feedback, code: str) -> sp.Expr | None:
    """The reference with one known mistake made (None when the mistake does not apply to ``form``)."""
    forms = _loop_forms(feedback)
    ol = forms["open_loop_tf"]
    if code == "kpot_convention":
        return _loop_forms(_OTHER[feedback])[form]
    if code == "missing_factor_4":
        return forms[form].subs(_SYM["beta"], _SYM["beta"] / 4)
    if code == "damping_omitted":
        return forms[form].subs(_SYM["B"], 0)
    if code == "open_loop_given" and form == "closed_loop_tf":
        return ol
    if code == "closed_loop_given" and form == "open_loop_tf":
        return forms["closed_loop_tf"]
    if code == "positive_feedback" and form == "closed_loop_tf":
        return ol / (1 - ol)
    if code == "positive_feedback" and form == "char_poly":
        n, d = sp.fraction(sp.together(ol))
        return sp.expand(d - n)
    return None


#: mistake code -> forms it applies to
TF_MISTAKES: dict[str, tuple[str, ...]] = {
    "kpot_convention": FORMS,
    "missing_factor_4": FORMS,
    "damping_omitted": FORMS,
    "open_loop_given": ("closed_loop_tf",),
    "closed_loop_given": ("open_loop_tf",),
    "positive_feedback": ("closed_loop_tf", "char_poly"),
}


@lru_cache(maxsize=64)
def reference(form: str, feedback: Feedback, mistake: str | None = None) -> RatFunc:
    """The reference (or, with ``mistake``, the wrong) expression as an exact rational function."""
    expr = _loop_forms(feedback)[form] if mistake is None else _transformed(form, feedback, mistake)
    if expr is None:
        raise KeyError(f"mistake {mistake!r} does not apply to {form}")
    return sympy_to_ratfunc(expr)


def reference_symbols(form: str, feedback: Feedback) -> frozenset[str]:
    """Names of the symbols in the reference expression."""
    return frozenset(s.name for s in _loop_forms(feedback)[form].free_symbols)


def has_s(p: PolyElement) -> bool:
    return p.degree(_S) > 0


def lc_s(p: PolyElement) -> PolyElement:
    """Leading coefficient of ``p`` as a polynomial in s (a polynomial in the other symbols)."""
    return p.coeff_wrt(_S, p.degree(_S))


def equivalent(form: str, answer: RatFunc, ref: RatFunc) -> bool:
    """Exact equivalence; characteristic polynomials up to a factor free of s."""
    if form != "char_poly":
        return answer == ref
    p, q = answer.num * ref.den, ref.num * answer.den
    if not p or not q:
        return False
    return p * lc_s(q) == q * lc_s(p)


def char_poly_of(form: str, answer: RatFunc) -> PolyElement:
    """The characteristic polynomial an answer implies (common factors cancelled)."""
    if form == "char_poly":
        return answer.num
    num, den = answer.num.cancel(answer.den)
    if form == "open_loop_tf":
        num, den = num.cancel(den + num)
    return den


def _names(exps: list[tuple[str, int]]) -> str:
    return "·".join(n if e == 1 else f"{n}^{e}" for n, e in exps)


def _factor_text(num: PolyElement, den: PolyElement) -> str | None:
    """Describe the s-free ratio num/den when it is a constant or a product of symbols
    (a phrase starting with a verb), else None."""
    if not (num.is_term and den.is_term):
        return None
    (mn, cn), = num.terms()
    (md, cd), = den.terms()
    coeff = sp.Rational(cn) / sp.Rational(cd)
    diff = [(n, a - b) for n, a, b in zip(_SYM, mn, md)]
    extra, missing = [(n, e) for n, e in diff if e > 0], [(n, -e) for n, e in diff if e < 0]
    parts = []
    if coeff < 0:
        parts.append("has the wrong sign")
        coeff = -coeff
    if coeff != 1:
        parts.append(f"is missing a factor {coeff.q}" if coeff.p == 1 else f"is {coeff} times what it should be")
    if extra:
        parts.append(f"has an extra factor {_names(extra)}")
    if missing:
        parts.append(f"is missing a factor {_names(missing)}")
    return " and ".join(parts) if parts else None


def _term_difference(a: PolyElement, r: PolyElement) -> str | None:
    """'is missing a term involving B' when a's terms are a subset of r's (or the reverse)."""
    ta, tr = dict(a.terms()), dict(r.terms())
    for small, big, verb in ((ta, tr, "is missing"), (tr, ta, "has an extra")):
        if all(big.get(m) == c for m, c in small.items()) and len(big) > len(small):
            common = {n for m in small for n, e in zip(_SYM, m) if e}
            odd = sorted({n for m in big if m not in small for n, e in zip(_SYM, m) if e} - common)
            what = f" involving {', '.join(odd)}" if odd else ""
            return f"{verb} a term{what}"
    return None


def _term_name(k: int) -> str:
    return {0: "the constant term (s^0)", 1: "the s coefficient"}.get(k, f"the s^{k} coefficient")


def coefficient_report(answer_poly: PolyElement, ref_poly: PolyElement, *, reveal: bool = True) -> list[str]:
    """How the monic characteristic polynomials differ, coefficient by coefficient (highest first).
    Without ``reveal`` only which coefficients differ (no factors, terms or symbols of the model)."""
    da, dr = answer_poly.degree(_S), ref_poly.degree(_S)
    if not answer_poly:  # sympy gives the zero polynomial degree -inf
        return ["your characteristic polynomial is zero; the loop's is of degree " + str(dr) + " in s"]
    if da != dr:
        return [f"your characteristic polynomial is of degree {da} in s; the loop's is of degree {dr}"]
    la, lr = lc_s(answer_poly), lc_s(ref_poly)
    out = []
    for k in range(dr - 1, -1, -1):
        a, r = answer_poly.coeff_wrt(_S, k), ref_poly.coeff_wrt(_S, k)
        if a * lr == r * la:
            continue
        if not reveal:
            out.append(f"{_term_name(k)} of the characteristic polynomial differs from the model's")
        elif not a:
            out.append(f"{_term_name(k)} is missing")
        elif not r:
            out.append(f"{_term_name(k)} should not be there")
        else:
            num, den = (a * lr).cancel(r * la)
            how = _factor_text(num, den) or _term_difference(a * lr, r * la)
            out.append(f"{_term_name(k)} {how}" if how else f"{_term_name(k)} is wrong")
    return out


def diagnose(form: str, answer: RatFunc, ref: RatFunc, answer_symbols: frozenset[str],
             ref_symbols: frozenset[str], *, reveal: bool = True) -> list[str]:
    """Student-facing sentences on what differs (no reference expression is quoted). Without
    ``reveal`` (``grader check``) only which coefficient or part differs: never the missing or
    extra factors, terms, or which symbols the model uses."""
    notes = []
    foreign = sorted(answer_symbols - ref_symbols)
    if foreign:
        notes.append(f"it uses {', '.join(foreign)}, which do not appear in this loop" if reveal
                     else "it uses a symbol that does not appear in this loop")
    if form != "char_poly" and (has_s(answer.den) or has_s(answer.num)) is False:
        return notes + ["it does not depend on s"]
    report = coefficient_report(char_poly_of(form, answer), char_poly_of(form, ref), reveal=reveal)
    if report:
        return notes + report
    if not reveal:
        return notes + ["the characteristic polynomial is right, but the gain (numerator) differs from the model's"]
    num, den = (answer.num * ref.den).cancel(ref.num * answer.den)
    how = _factor_text(num, den)
    return notes + ["the characteristic polynomial is right, but " + (f"the gain {how}" if how else "the numerator differs")]
