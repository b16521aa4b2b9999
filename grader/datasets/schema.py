"""The lab dataset manifest (``manifest.json`` or ``manifest.yaml``), validated with pydantic.

Quantities in ``given`` are strings with units (``"29 lbf"``); they are checked
for dimension here and converted to internal floats by :meth:`Given.values`.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator
from pydantic_core import PydanticCustomError

from grader.errors import ModelError
from grader.model.params import G_IN_PER_S2, Controller, mass_from_weight, piston_area
from grader.units import quantity_to_float

RunKind = Literal["step", "ramp", "instability"]

#: given field -> internal unit (the dimension every value must have)
GIVEN_UNITS: dict[str, str] = {
    "weight": "lbf",
    "mass": "lbf*s**2/in",
    "bore": "in",
    "rod": "in",
    "supply_pressure": "psi",
    "Kamp": "mA/V",
    "i_max": "mA",
    "sample_time": "s",
}
#: Range of a given value in its unit of :data:`GIVEN_UNITS` (the rod may be 0).
GIVEN_RANGE = (1e-9, 1e9)
_NAME = re.compile(r"^[A-Za-z0-9_.\-]{1,64}$")


def number_as_text(v: object) -> object:
    """A bare JSON/YAML number (``4e-4``) as the text it reads as, a quantity in its field's unit; else ``v``."""
    return str(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else v


class Given(BaseModel):
    """Values the lab handout gives the students, as quantity strings."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    weight: str | None = None
    mass: str | None = None
    bore: str = "0.5 in"
    rod: str = "0.25 in"
    supply_pressure: str = "1000 psi"
    Kamp: str = "5 mA/V"
    i_max: str = "50 mA"
    sample_time: str = "0.001 s"

    @field_validator("*", mode="before")
    @classmethod
    def _as_text(cls, v: object) -> object:
        return number_as_text(v)

    @model_validator(mode="after")
    def _check(self) -> Given:
        if (self.weight is None) == (self.mass is None):
            raise ValueError("give exactly one of 'weight' (e.g. '29 lbf') or 'mass'")
        values = self.values()
        for name in ("bore", "supply_pressure", "Kamp", "i_max", "sample_time"):
            if values[name] <= 0:
                raise ValueError(f"{name} must be positive, got {getattr(self, name)!r}")
        if values["M"] <= 0:
            raise ValueError("the moving mass must be positive")
        sizes = {n: values[n] for n in ("bore", "supply_pressure", "Kamp", "i_max", "sample_time")}
        sizes["weight" if self.weight is not None else "mass"] = values["M"] * (G_IN_PER_S2 if self.weight else 1.0)
        for name, v in sizes.items():  # beyond these, products of them overflow a double somewhere in the loop
            if not GIVEN_RANGE[0] <= v <= GIVEN_RANGE[1]:
                raise ValueError(f"{name} = {getattr(self, name)!r} is outside the range a rig can have "
                                 f"({GIVEN_RANGE[0]:g} to {GIVEN_RANGE[1]:g} {GIVEN_UNITS[name]})")
        piston_area(values["bore"], values["rod"])
        return self

    def values(self) -> dict[str, float]:
        """Internal floats: bore, rod [in], supply_pressure [psi], Kamp [mA/V], i_max [mA],
        sample_time [s], M [lbf·s²/in] and A [in²]."""
        out = {
            name: quantity_to_float(getattr(self, name), GIVEN_UNITS[name], where=f"given.{name}")
            for name in ("bore", "rod", "supply_pressure", "Kamp", "i_max", "sample_time")
        }
        if self.weight is not None:
            out["M"] = mass_from_weight(quantity_to_float(self.weight, "lbf", where="given.weight"))
        else:
            out["M"] = quantity_to_float(self.mass or "", "lbf*s**2/in", where="given.mass")
        try:
            out["A"] = piston_area(out["bore"], out["rod"]) if out["rod"] < out["bore"] else float("nan")
        except OverflowError:  # a bore beyond 1e154 in
            out["A"] = math.inf
        return out


#: Largest controller gain a manifest may give (the paper's are 10 to 60; beyond this a loop overflows doubles).
MAX_GAIN = 1e12
#: Most runs a manifest may list (the paper's lab records six).
MAX_RUNS = 100


class ControllerSpec(BaseModel):
    """Gains of one run, in the units the manifest's ``feedback`` implies."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    Kp: float = Field(ge=0, le=MAX_GAIN, allow_inf_nan=False)
    Ki: float = Field(default=0.0, ge=0, le=MAX_GAIN, allow_inf_nan=False)
    Kd: float = Field(default=0.0, ge=0, le=MAX_GAIN, allow_inf_nan=False)

    @field_validator("Kp", "Ki", "Kd", mode="before")
    @classmethod
    def _not_true_or_false(cls, v: object) -> object:
        if isinstance(v, bool):  # pydantic would read true as 1
            raise PydanticCustomError("float_type", "Input should be a valid number")
        return v

    @model_validator(mode="after")
    def _a_controller(self) -> ControllerSpec:
        try:
            Controller(self.Kp, self.Ki, self.Kd)  # the model's own rules (Kp > 0 or Ki > 0)
        except ModelError as exc:
            raise ValueError(str(exc)) from None
        return self


class RunSpec(BaseModel):
    """One closed-loop run: its name, CSV file, kind and controller gains."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    name: str
    file: str
    kind: RunKind
    controller: ControllerSpec

    @field_validator("name", "file")
    @classmethod
    def _safe_name(cls, v: str) -> str:
        if not _NAME.match(v) or v.startswith("."):
            raise ValueError(f"{v!r} must be a plain file name (letters, digits, _ . -)")
        return v


class Manifest(BaseModel):
    """``manifest.json``: what the dataset holds and where."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    station: str = "station"
    given: Given
    feedback: Literal["volts", "inches"] = "volts"
    calibration: str | None = None
    flow_test: str | None = None
    friction: str | None = None
    runs: list[RunSpec] = Field(default_factory=list, max_length=MAX_RUNS)

    @field_validator("station")
    @classmethod
    def _text(cls, v: str) -> str:
        try:
            v.encode("utf-8")
        except UnicodeEncodeError:  # an unpaired surrogate (JSON's \ud800) that no report could write
            raise ValueError("must be text that UTF-8 can write (it holds an unpaired surrogate)") from None
        return v

    @field_validator("calibration", "flow_test", "friction")
    @classmethod
    def _safe_file(cls, v: str | None) -> str | None:
        if v is not None and (not _NAME.match(v) or v.startswith(".")):
            raise ValueError(f"{v!r} must be a plain file name in the dataset folder")
        return v

    @model_validator(mode="after")
    def _unique_runs(self) -> Manifest:
        names = [r.name for r in self.runs]
        dupes = sorted({n for n in names if names.count(n) > 1})
        if dupes:
            raise ValueError(f"run names must be unique; repeated: {', '.join(dupes)}")
        return self


@dataclass(frozen=True)
class TableSpec:
    """Required and optional columns of a CSV, with the internal unit of each."""

    required: dict[str, str]
    optional: dict[str, str]
    min_rows: int


CALIBRATION = TableSpec({"position": "in", "voltage": "V"}, {}, 3)
FLOW_TEST = TableSpec({"input": "V", "flow": "in**3/s"}, {}, 6)
FRICTION = TableSpec({"speed": "in/s", "force": "lbf"}, {}, 3)
RUN = TableSpec({"t": "s", "r": "in", "y": "in"}, {"u": "V"}, 20)
