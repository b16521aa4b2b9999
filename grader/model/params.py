"""Rig parameters and controller gains as frozen dataclasses of plain floats.

All values are in the package's coherent inch-pound-second system
(see :mod:`grader.units`): A [in²], M [lbf·s²/in], Kamp [mA/V], Kq [in³/s/mA],
Kpot [V/in], beta_over_Vt [psi/in³], Kce [in³/s/psi], B [lbf·s/in],
sample_time [s], supply_pressure [psi], i_max [mA].
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Literal, Protocol

from grader.errors import ModelError

Feedback = Literal["volts", "inches"]
G_IN_PER_S2 = 386.08858267716535  # standard gravity [in/s²]


def piston_area(bore: float, rod: float) -> float:
    """Annulus area [in²] of a through-rod cylinder from bore and rod diameters [in]."""
    if not 0.0 <= rod < bore:
        raise ModelError(f"rod diameter {rod} in must be smaller than bore {bore} in")
    return math.pi / 4.0 * (bore**2 - rod**2)


def mass_from_weight(weight: float) -> float:
    """Mass [lbf·s²/in] of a weight [lbf] under standard gravity."""
    return weight / G_IN_PER_S2


@dataclass(frozen=True, slots=True)
class RigParams:
    """The linear model's parameters (internal units, see module docstring)."""

    A: float
    M: float
    Kamp: float
    Kq: float
    Kpot: float
    beta_over_Vt: float
    Kce: float
    B: float = 0.0
    sample_time: float = 0.001
    feedback: Feedback = "volts"
    supply_pressure: float = 1000.0
    i_max: float = 50.0

    def __post_init__(self) -> None:
        for name in ("A", "M", "Kamp", "Kq", "Kpot", "beta_over_Vt"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ModelError(f"{name} must be a positive finite number, got {value}")
        for name in ("Kce", "B", "sample_time"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ModelError(f"{name} must be a non-negative finite number, got {value}")
        if self.feedback not in ("volts", "inches"):
            raise ModelError(f"feedback must be 'volts' or 'inches', got {self.feedback!r}")

    @property
    def k_fb(self) -> float:
        """Gain from position error [in] to the controller's input: Kpot [V/in] or 1."""
        return self.Kpot if self.feedback == "volts" else 1.0

    def with_(self, **changes: float | str) -> RigParams:
        """A copy with some fields changed."""
        return replace(self, **changes)


class Gains(Protocol):
    """Anything hashable with PID gains (a :class:`Controller`, or a submitted design's gains)."""

    @property
    def Kp(self) -> float: ...  # noqa: N802
    @property
    def Ki(self) -> float: ...  # noqa: N802
    @property
    def Kd(self) -> float: ...  # noqa: N802
    def __hash__(self) -> int: ...


@dataclass(frozen=True, slots=True)
class Controller:
    """Parallel PID gains acting on the error in the feedback convention's units.

    volts: Kp [V/V], Ki [1/s], Kd [s]; inches: Kp [V/in], Ki [V/(in·s)], Kd [V·s/in].
    """

    Kp: float
    Ki: float = 0.0
    Kd: float = 0.0

    def __post_init__(self) -> None:
        for name in ("Kp", "Ki", "Kd"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ModelError(f"controller gain {name} must be non-negative and finite, got {value}")
        if self.Kp == 0 and self.Ki == 0:
            raise ModelError("controller needs Kp > 0 or Ki > 0")

    @property
    def kind(self) -> str:
        """'P', 'PI', 'PD' or 'PID'."""
        return "P" + ("I" if self.Ki else "") + ("D" if self.Kd else "")
