"""Symbolic block-diagram reduction (sympy) in the course's symbols.

The plant follows Merritt: valve flow ``Q = Kq·i − Kc·PL``; continuity
``Q = A·s·X + Ctp·PL + Vt/(4β)·s·PL`` (Kce = Kc + Ctp); and force balance
``A·PL = (M s² + B s)·X``. The controller ``Kp + Ki/s + Kd·s`` acts on the
position error scaled by Kpot (``volts``) or already in inches (``inches``);
the amplifier turns volts into current with Kamp.

The reduction solves these equations, so it is independent of the closed-form
coefficients in :mod:`grader.model.linear` (tests compare the two).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import sympy as sp

from grader.model.params import Feedback

S = sp.Symbol("s")
Kp, Ki, Kd = sp.symbols("Kp Ki Kd", nonnegative=True)
Kamp, Kq, Kce, A, M, B, beta, Vt, Kpot = sp.symbols("Kamp Kq Kce A M B beta Vt Kpot", positive=True)

#: Every symbol a student may use in a transfer-function answer, by name.
COURSE_SYMBOLS: dict[str, sp.Symbol] = {
    sym.name: sym for sym in (S, Kp, Ki, Kd, Kamp, Kq, Kce, A, M, B, beta, Vt, Kpot)
}


@dataclass(frozen=True)
class SymbolicLoop:
    """The reduced loop for one controller form and feedback convention."""

    plant: sp.Expr  # X/I [in/mA]
    controller: sp.Expr
    open_loop: sp.Expr  # L(s), dimensionless
    closed_loop: sp.Expr  # Y/R
    char_poly: sp.Poly  # monic in s


def _plant() -> sp.Expr:
    X, PL, I = sp.symbols("X P_L I")
    q_valve = Kq * I - Kce * PL  # leakage lumped into Kce
    eqs = [
        sp.Eq(q_valve, A * S * X + Vt / (4 * beta) * S * PL),
        sp.Eq(A * PL, (M * S**2 + B * S) * X),
    ]
    sol = sp.solve(eqs, [X, PL], dict=True)[0]
    return sp.factor(sp.cancel(sol[X] / I))


@lru_cache(maxsize=16)
def reduce_loop(feedback: Feedback = "volts", kind: str = "P") -> SymbolicLoop:
    """Reduce the block diagram for controller ``kind`` in {P, PI, PD, PID}."""
    plant = _plant()
    controller = Kp + (Ki / S if "I" in kind else 0) + (Kd * S if "D" in kind else 0)
    k_fb = Kpot if feedback == "volts" else sp.Integer(1)
    open_loop = sp.cancel(controller * Kamp * plant * k_fb)
    closed_loop = sp.cancel(open_loop / (1 + open_loop))
    _, den = sp.fraction(sp.together(closed_loop))
    poly = sp.Poly(sp.expand(den), S)
    char_poly = sp.Poly(sp.expand(poly.as_expr() / poly.LC()), S)
    return SymbolicLoop(plant, sp.simplify(controller), open_loop, closed_loop, char_poly)


def char_poly_coeffs(feedback: Feedback = "volts", kind: str = "P") -> list[sp.Expr]:
    """Monic characteristic-polynomial coefficients, highest power first."""
    return [sp.simplify(c) for c in reduce_loop(feedback, kind).char_poly.all_coeffs()]
