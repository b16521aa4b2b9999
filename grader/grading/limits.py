"""Resource limits applied to untrusted submissions (sizes, expression complexity, time)."""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

from grader.errors import ExpressionError


@dataclass(frozen=True)
class Limits:
    """Limits on what a submission may contain; every one is enforced before parsing or evaluating."""

    max_text_bytes: int = 1_000_000  # JSON / YAML file
    max_xlsx_bytes: int = 20_000_000  # XLSX file (compressed)
    max_xlsx_unzipped: int = 40_000_000  # total uncompressed size of its parts (zip bombs)
    max_string: int = 2_000  # any one string in a submission
    max_nodes: int = 400  # AST nodes in an expression
    max_exponent: int = 12  # |n| in x**n
    max_terms: int = 1_000  # bound on polynomial terms an expression can expand to (numerator or denominator)
    max_number: float = 1e15  # magnitude of a numeric literal in an expression
    expr_seconds: float = 2.0  # wall-clock limit for checking one expression
    max_poles: int = 12  # poles per gain
    max_gains: int = 24  # gains in a pole answer
    max_yaml_events: int = 50_000


DEFAULT_LIMITS = Limits()


@contextmanager
def time_limit(seconds: float, what: str) -> Iterator[None]:
    """Raise :class:`ExpressionError` if the block runs longer than ``seconds``.

    Uses SIGALRM, so it only arms in the main thread of a POSIX process (workers of
    the batch pool run tasks in their main thread); elsewhere the static limits of
    :class:`Limits` alone bound the work.
    """
    usable = hasattr(signal, "setitimer") and threading.current_thread() is threading.main_thread()
    if not usable or seconds <= 0:
        yield
        return

    def _expired(signum: int, frame: object) -> None:
        raise ExpressionError(f"{what}: took longer than {seconds:g} s to check; simplify it")

    previous = signal.signal(signal.SIGALRM, _expired)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
