"""Student expressions (transfer functions, polynomials) read through an AST whitelist.

The text is parsed by :func:`ast.parse` (which never executes anything) and every node
is checked against a whitelist: numbers, the course's symbols, ``+ - * / **`` (``^`` is
read as ``**``), unary signs and parentheses. No names outside the course, no calls,
attributes, subscripts, comparisons or strings. Before parsing, a small tokenizer
(:func:`implicit_products`) writes the implicit products students type as ``*``:
``4 beta Kq A``, ``4beta``, ``2(s+1)``, ``(s+1)(s+2)``, ``Kp Kamp``. A name is read whole
(``Kpot`` is one symbol, never K*p*o*t), and an implicit product binds like ``*`` (so
``1/2s`` is s/2: write ``1/(2s)``). Exponents must be small integer
literals, and a static bound on how many polynomial terms the expression can expand
to is enforced before anything is built. Nothing here calls ``eval``, ``sympify`` or
``parse_expr``: sympy objects and exact rational functions are built from the checked
tree (:func:`to_ratfunc`, :func:`to_sympy`).
"""

from __future__ import annotations

import ast
import keyword
import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import sympy as sp
from sympy.polys.rings import PolyElement, ring

from grader.errors import ExpressionError
from grader.grading.limits import DEFAULT_LIMITS, Limits
from grader.model.symbolic import COURSE_SYMBOLS
from grader.units import SIGNS, plain_powers

#: the polynomial ring over QQ in the course's symbols, ``s`` first
RING, *_GENS = ring(",".join(COURSE_SYMBOLS), sp.QQ)
GENS: dict[str, PolyElement] = dict(zip(COURSE_SYMBOLS, _GENS))
#: accepted spellings of the course's symbols
ALIASES: dict[str, str] = {
    "K_p": "Kp", "K_i": "Ki", "K_d": "Kd", "K_amp": "Kamp", "K_a": "Kamp", "K_q": "Kq", "K_ce": "Kce",
    "K_pot": "Kpot", "V_t": "Vt", "β": "beta", "Beta": "beta",
}
_OPS = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/", ast.Pow: "**"}
_LHS = re.compile(r"^[A-Za-z_(){}\s/]*$")
_TOKEN = re.compile(r"(?P<num>(?:\d[\d_]*(?:\.[\d_]*)?|\.\d[\d_]*)(?:[eE][+-]?\d+)?)|(?P<name>[^\W\d]\w*)"
                    r"|(?P<space>\s+)|(?P<other>.)", re.S)
_TRANSLATE = str.maketrans({"^": "**", **SIGNS})


class RatFunc:
    """An exact rational function ``num/den`` of ring polynomials, kept unreduced (no gcd)."""

    __slots__ = ("num", "den")

    def __init__(self, num: PolyElement, den: PolyElement | None = None) -> None:
        self.num, self.den = num, RING.one if den is None else den

    def __add__(self, o: RatFunc) -> RatFunc:
        return RatFunc(self.num * o.den + o.num * self.den, self.den * o.den)

    def __sub__(self, o: RatFunc) -> RatFunc:
        return RatFunc(self.num * o.den - o.num * self.den, self.den * o.den)

    def __mul__(self, o: RatFunc) -> RatFunc:
        return RatFunc(self.num * o.num, self.den * o.den)

    def __truediv__(self, o: RatFunc) -> RatFunc:
        if not o.num:
            raise ExpressionError("division by zero")
        return RatFunc(self.num * o.den, self.den * o.num)

    def __pow__(self, n: int) -> RatFunc:
        if n == 0 and not self.num:
            raise ExpressionError("0**0 is undefined")
        if n < 0:
            if not self.num:
                raise ExpressionError("division by zero")
            return RatFunc(self.den**-n, self.num**-n)
        return RatFunc(self.num**n, self.den**n)

    def __neg__(self) -> RatFunc:
        return RatFunc(-self.num, self.den)

    def __pos__(self) -> RatFunc:
        return self

    def __eq__(self, o: object) -> bool:
        return isinstance(o, RatFunc) and self.num * o.den == o.num * self.den

    __hash__ = None  # type: ignore[assignment]

    def is_zero(self) -> bool:
        return not self.num


@dataclass(frozen=True)
class Expression:
    """A checked expression: its (right-hand side) text, whitelisted tree and symbols used."""

    text: str
    tree: ast.expr
    symbols: frozenset[str]


def _strip_equation(text: str) -> str:
    """``"T(s) = rhs"`` -> rhs; ``"poly = 0"`` -> poly."""
    if text.count("=") == 0:
        return text
    if text.count("=") > 1:
        raise ExpressionError("more than one '=' sign")
    lhs, rhs = (part.strip() for part in text.split("="))
    if rhs == "0":
        return lhs
    if _LHS.match(lhs):
        return rhs
    raise ExpressionError(f"left of '=' must be a name such as 'X(s)/R(s)', got {lhs!r}")


def _kind(match: re.Match[str]) -> str:
    """The token's role for implicit products: ``num``, ``sym`` (a name that is not a keyword),
    ``(``, ``)``, or ``other``."""
    kind, text = match.lastgroup or "other", match.group()
    if kind == "name":
        return "other" if keyword.iskeyword(text) else "sym"
    return text if kind == "other" and text in "()" else kind


def _implied(left: str, right: str, left_text: str) -> bool:
    """Whether a ``*`` is implied between two adjacent tokens (spaces between them allowed)."""
    if left not in ("num", "sym", ")") or right not in ("sym", "("):
        return False
    # a name before '(' is a product only for the course's symbols (else a refused call, e.g. exp(s))
    return right != "(" or left != "sym" or ALIASES.get(left_text, left_text) in COURSE_SYMBOLS


def implicit_products(text: str) -> str:
    """``text`` with a ``*`` written at each implicit product (a tokenizer; nothing is evaluated).

    A product is implied between a number, name or ``)`` and a following name or ``(``:
    ``4 beta Kq A``, ``4beta``, ``2(s+1)``, ``(s+1)(s+2)``, ``Kp Kamp``, ``Kp(s+1)``. Names are read
    whole (``Kpot`` is one symbol) and keywords are never operands. Only ``*`` is ever inserted.
    """
    out: list[str] = []
    prev, prev_text = "other", ""
    for m in _TOKEN.finditer(text):
        kind = _kind(m)
        if kind == "space":
            out.append(m.group())
            continue
        if _implied(prev, kind, prev_text):
            at = len(out)
            while at and out[at - 1].isspace():
                at -= 1
            out.insert(at, "*")
        out.append(m.group())
        prev, prev_text = kind, m.group()
    return "".join(out)


def _number(node: ast.Constant, limits: Limits) -> Fraction:
    v = node.value
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ExpressionError(f"{v!r} is not allowed (only numbers and the course's symbols)")
    if isinstance(v, int):
        # never convert a huge int to float (OverflowError) nor repr it (int-digit limit)
        if v.bit_length() > 64 or abs(v) > limits.max_number:
            raise ExpressionError("number is out of range (too large)")
        return Fraction(v)
    if not math.isfinite(v) or abs(v) > limits.max_number:
        raise ExpressionError(f"number {v!r} is out of range")
    return Fraction(repr(v))


def _exponent(node: ast.expr) -> int:
    """The integer literal of an exponent node (``2``, ``-1``, ``(3)``)."""
    sign = 1
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        sign, node = (-1 if isinstance(node.op, ast.USub) else 1), node.operand
    if not (isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) and not isinstance(node.value, bool)):
        raise ExpressionError("exponents must be whole numbers written as numbers, e.g. s**2")
    v = node.value
    if isinstance(v, int):
        if v.bit_length() > 64:
            raise ExpressionError("exponent is out of range (too large)")
        return sign * v
    if not math.isfinite(v) or v != int(v):
        raise ExpressionError(f"exponent {v!r} is not a whole number")
    return sign * int(v)


class _Checker:
    """Walks the tree once: whitelist, node count, and a bound on expanded term counts."""

    def __init__(self, limits: Limits) -> None:
        self.limits, self.nodes, self.symbols = limits, 0, set()

    def cap(self, n: int) -> int:
        if n > self.limits.max_terms:
            raise ExpressionError("expression too large: it would expand to too many terms; simplify it")
        return n

    def visit(self, node: ast.expr) -> tuple[int, int]:
        """(bound on numerator terms, bound on denominator terms)."""
        self.nodes += 1
        if self.nodes > self.limits.max_nodes:
            raise ExpressionError(f"expression has more than {self.limits.max_nodes} parts")
        if isinstance(node, ast.Constant):
            _number(node, self.limits)
            return 1, 1
        if isinstance(node, ast.Name):
            name = ALIASES.get(node.id, node.id)
            if name not in COURSE_SYMBOLS:
                raise ExpressionError(f"unknown symbol {node.id!r} (use the course's symbols: {', '.join(COURSE_SYMBOLS)})")
            self.symbols.add(name)
            return 1, 1
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            return self.visit(node.operand)
        if isinstance(node, ast.BinOp) and type(node.op) in _OPS:
            return self.binop(node)
        raise ExpressionError(_refusal(node))

    def binop(self, node: ast.BinOp) -> tuple[int, int]:
        if isinstance(node.op, ast.Pow):
            n = _exponent(node.right)
            if abs(n) > self.limits.max_exponent:
                raise ExpressionError(f"exponent {n} is larger than {self.limits.max_exponent}")
            self.nodes += 1
            a, b = self.visit(node.left)
            a, b = (b, a) if n < 0 else (a, b)
            k = abs(n)
            return self.cap(min(a**k, math.comb(a + k - 1, k))), self.cap(min(b**k, math.comb(b + k - 1, k)))
        (an, ad), (bn, bd) = self.visit(node.left), self.visit(node.right)
        if isinstance(node.op, (ast.Add, ast.Sub)):
            return self.cap(an * bd + bn * ad), self.cap(ad * bd)
        if isinstance(node.op, ast.Mult):
            return self.cap(an * bn), self.cap(ad * bd)
        return self.cap(an * bd), self.cap(ad * bn)


def _refusal(node: ast.AST) -> str:
    if isinstance(node, ast.Call):
        return "function calls are not allowed (only numbers, the course's symbols, + - * / ^ and parentheses)"
    if isinstance(node, ast.Attribute):
        return "attribute access ('.') is not allowed"
    if isinstance(node, ast.BinOp):
        return f"operator {type(node.op).__name__} is not allowed (only + - * / ^)"
    return f"{type(node).__name__} is not allowed (only numbers, the course's symbols, + - * / ^ and parentheses)"


def parse_expression(text: Any, *, limits: Limits = DEFAULT_LIMITS) -> Expression:
    """Check ``text`` against the whitelist and limits; raises :class:`ExpressionError` with the reason."""
    if not isinstance(text, str):
        raise ExpressionError(f"expected the expression as text, got {type(text).__name__}")
    if len(text) > limits.max_string:
        raise ExpressionError(f"expression longer than {limits.max_string} characters")
    body = _strip_equation(plain_powers(text).translate(_TRANSLATE).strip())
    if not body:
        raise ExpressionError("empty expression")
    body = implicit_products(body)
    try:
        tree = ast.parse(body, mode="eval").body
    except SyntaxError as exc:
        if any(w in (exc.msg or "") for w in ("never closed", "unmatched", "does not match")):  # brackets
            raise ExpressionError(f"cannot read it: {exc.msg}") from None
        col = f" near column {exc.offset}" if exc.offset else ""
        raise ExpressionError(f"cannot read it{col}; write products with * or a space (e.g. 4*A*beta or 4 A beta) "
                              "and powers with ^") from None
    except (ValueError, RecursionError, MemoryError, OverflowError):
        raise ExpressionError("cannot read it: too deeply nested or too long") from None
    checker = _Checker(limits)
    try:
        checker.visit(tree)
    except RecursionError:
        raise ExpressionError("expression too deeply nested") from None
    return Expression(text=body, tree=tree, symbols=frozenset(checker.symbols))


def _fold(node: ast.expr, symbol: Callable[[str], Any], number: Callable[[Fraction], Any]) -> Any:
    if isinstance(node, ast.Constant):
        return number(_number(node, DEFAULT_LIMITS))
    if isinstance(node, ast.Name):
        return symbol(ALIASES.get(node.id, node.id))
    if isinstance(node, ast.UnaryOp):
        inner = _fold(node.operand, symbol, number)
        return -inner if isinstance(node.op, ast.USub) else inner
    assert isinstance(node, ast.BinOp)
    left = _fold(node.left, symbol, number)
    if isinstance(node.op, ast.Pow):
        return left ** _exponent(node.right)
    right = _fold(node.right, symbol, number)
    op = type(node.op)
    if op is ast.Add:
        return left + right
    if op is ast.Sub:
        return left - right
    if op is ast.Mult:
        return left * right
    return left / right


def to_ratfunc(expr: Expression) -> RatFunc:
    """The exact rational function of a checked expression (raises ExpressionError on 1/0)."""
    return _fold(expr.tree, lambda n: RatFunc(GENS[n]), lambda f: RatFunc(RING(sp.Rational(f.numerator, f.denominator))))


def to_sympy(expr: Expression) -> sp.Expr:
    """A sympy expression of a checked expression (built node by node, never from text)."""
    return _fold(expr.tree, COURSE_SYMBOLS.__getitem__, lambda f: sp.Rational(f.numerator, f.denominator))


def sympy_to_ratfunc(expr: sp.Expr) -> RatFunc:
    """Convert a trusted sympy expression in the course's symbols (a reference) to a RatFunc."""
    if expr.is_Symbol:
        return RatFunc(GENS[expr.name])
    if expr.is_Rational:
        return RatFunc(RING(expr))
    if expr.is_Add or expr.is_Mul:
        parts = [sympy_to_ratfunc(a) for a in expr.args]
        out = parts[0]
        for p in parts[1:]:
            out = out + p if expr.is_Add else out * p
        return out
    if expr.is_Pow and expr.exp.is_Integer:
        return sympy_to_ratfunc(expr.base) ** int(expr.exp)
    raise ExpressionError(f"reference expression has an unsupported part: {type(expr).__name__}")
