"""Rubric files (``rubrics/*.yaml``), validated with pydantic.

Per item: points, expected unit, tolerance, the key quantity it is checked against
(plus alternatives), dependencies for error carried forward with its credit, the
credit of a unit slip, and the known mistakes it recognises (catalog codes with
partial credit and feedback). Credits are fractions of the item's points.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from grader import untrusted
from grader.errors import GraderError, RubricError, validation_message
from grader.grading.ecf import RECOMPUTE
from grader.grading.items import ITEMS
from grader.grading.mistakes import CATALOG
from grader.units import parse_quantity, parse_unit, pretty_unit

_FORBID = ConfigDict(extra="forbid", frozen=True)


class Tolerance(BaseModel):
    """Accept when within ``relative`` (fraction) or ``absolute`` (a quantity in the item's unit, or a
    number in it) of the key, or matching to ``sig_figs`` significant figures, or (``interval``)
    inside the key's 95 % interval."""

    model_config = _FORBID
    relative: float | None = Field(default=None, ge=0, le=1)
    absolute: str | float | None = None
    sig_figs: int | None = Field(default=None, ge=1, le=12)
    interval: bool = False

    @model_validator(mode="after")
    def _some(self) -> Tolerance:
        if self.relative is None and self.absolute is None and self.sig_figs is None and not self.interval:
            raise ValueError("give at least one of relative, absolute, sig_figs or interval")
        return self

    def accepts(self, value: float, expected: float, *, absolute: float = 0.0,
                interval: tuple[float, float] | None = None) -> bool:
        """``absolute`` is this tolerance's absolute part already in the compared unit."""
        err = abs(value - expected)
        if self.relative is not None and err <= self.relative * abs(expected) * (1 + 1e-12):
            return True
        if self.absolute is not None and err <= absolute * (1 + 1e-12):
            return True
        if self.sig_figs is not None and expected != 0:
            step = 10 ** (math.floor(math.log10(abs(expected))) - self.sig_figs + 1)
            if err <= 0.5 * step * (1 + 1e-9):
                return True
        return bool(self.interval and interval and interval[0] <= value <= interval[1])

    def describe(self, unit: str = "") -> str:
        parts = []
        if self.relative is not None:
            parts.append(f"±{100 * self.relative:g} %")
        if self.absolute is not None:
            parts.append(f"±{self.absolute}" + (f" {pretty_unit(unit)}" if isinstance(self.absolute, (int, float)) and unit else ""))
        if self.sig_figs is not None:
            parts.append(f"{self.sig_figs} significant figures")
        return " or ".join(parts) or "the key's 95 % interval"


class MistakeRef(BaseModel):
    """A known mistake the item recognises: catalog code, credit (fraction of points), feedback override."""

    model_config = _FORBID
    code: str
    credit: float = Field(default=0.0, ge=0, le=1)
    feedback: str | None = None


class DesignSpec(BaseModel):
    """How a PD or PI design is judged (credits are fractions of the item's points)."""

    model_config = _FORBID
    stable_credit: float = Field(default=0.4, ge=0, le=1)
    goal_credit: float = Field(default=0.3, ge=0, le=1)
    claim_credit: float = Field(default=0.3, ge=0, le=1)
    min_reduction: float = Field(default=0.2, ge=0, le=1, description="PD: overshoot cut vs P alone, fraction")
    max_overshoot: float | None = Field(default=None, gt=0, description="PD: overshoot goal, fraction")
    max_ramp_error_fraction: float = Field(default=0.1, gt=0, le=1, description="PI: ramp error / P-alone ramp error")
    claim_relative: float = Field(default=0.25, ge=0)
    claim_absolute: float = Field(default=0.02, ge=0, description="overshoot fraction (PD) or inches (PI)")
    ramp_seconds: float = Field(default=4.0, gt=0, le=30)
    rig_penalty: float = Field(default=0.0, ge=0, le=1, description="credit lost when it fails on the rig")
    limit_cycle: str = "0.002 in"

    @model_validator(mode="after")
    def _sum(self) -> DesignSpec:
        if abs(self.stable_credit + self.goal_credit + self.claim_credit - 1.0) > 1e-9:
            raise ValueError("stable_credit + goal_credit + claim_credit must add up to 1")
        parse_quantity(self.limit_cycle, where="limit_cycle")
        return self


class RubricItem(BaseModel):
    """One graded answer item."""

    model_config = _FORBID
    points: float = Field(gt=0, allow_inf_nan=False)
    unit: str | None = None
    key: str | None = None
    also_accept: list[str] = []
    tolerance: Tolerance = Tolerance(relative=0.05)
    depends_on: list[str] = []
    ecf_credit: float = Field(default=0.8, ge=0, le=1)
    unit_mismatch_credit: float = Field(default=0.5, ge=0, le=1)
    mistakes: list[MistakeRef] = []
    design: DesignSpec | None = None
    title: str | None = None

    @field_validator("unit")
    @classmethod
    def _unit(cls, v: str | None) -> str | None:
        if v is not None:
            parse_unit(v, where="unit")
        return v


class Assignment(BaseModel):
    model_config = _FORBID
    name: str = "Hydraulic positioner lab"
    id: str = "0"


class Rubric(BaseModel):
    """A rubric file."""

    model_config = _FORBID
    rubric: str
    title: str = ""
    assignment: Assignment = Assignment()
    feedback_convention: Literal["volts", "inches"] = "volts"
    items: dict[str, RubricItem]

    @model_validator(mode="after")
    def _consistent(self) -> Rubric:
        if not self.items:
            raise ValueError("a rubric needs at least one item")
        for name, item in self.items.items():
            _check_item(name, item, self.items)
        self.order()
        return self

    def order(self) -> list[str]:
        """Item names with every dependency before its dependants (declaration order otherwise)."""
        done: list[str] = []
        visiting: set[str] = set()

        def visit(n: str) -> None:
            if n in done:
                return
            if n in visiting:
                raise ValueError(f"items {n!r} depends on itself through depends_on")
            visiting.add(n)
            for d in self.items[n].depends_on:
                visit(d)
            visiting.discard(n)
            done.append(n)

        for n in self.items:
            visit(n)
        return done

    def key_name(self, item: str) -> str:
        return self.items[item].key or item

    @property
    def max_score(self) -> float:
        return sum(i.points for i in self.items.values())


def _check_item(name: str, item: RubricItem, items: Mapping[str, RubricItem]) -> None:
    spec = ITEMS.get(name)
    if spec is None:
        raise ValueError(f"unknown item {name!r} (canonical items: {', '.join(ITEMS)})")
    for m in item.mistakes:
        known = CATALOG.get(m.code)
        if known is None or name not in known.items:
            codes = [c for c, k in CATALOG.items() if name in k.items]
            raise ValueError(f"items.{name}: mistake {m.code!r} is not in the catalog for {name} "
                             f"(known: {', '.join(codes) or 'none'})")
    for d in item.depends_on:
        if d not in items:
            raise ValueError(f"items.{name}.depends_on: {d!r} is not an item of this rubric")
    key = item.key or name
    if item.depends_on and (key not in RECOMPUTE or not set(item.depends_on) <= set(RECOMPUTE[key].inputs)):
        allowed = ", ".join(RECOMPUTE[key].inputs) if key in RECOMPUTE else "none"
        raise ValueError(f"items.{name}.depends_on: error carried forward for {key} can use {allowed}")
    if (spec.kind == "design") != (item.design is not None):
        raise ValueError(f"items.{name}: 'design' settings are for pd_design and pi_design (and required there)")


def load_rubric(path: str | Path) -> Rubric:
    """Read and validate a rubric file; raises :class:`RubricError` naming the file and field."""
    path = Path(path)
    if not path.is_file():
        raise RubricError(f"{path}: rubric file not found")
    try:
        raw = untrusted.load_yaml(path.read_text(encoding="utf-8"))
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise RubricError(f"{path.name}: not valid YAML ({str(exc).splitlines()[0]})") from None
    if not isinstance(raw, dict):
        raise RubricError(f"{path.name}: must hold a mapping at the top level")
    try:
        return Rubric.model_validate(raw)
    except ValidationError as exc:
        raise RubricError(validation_message(path.name, exc)) from None
    except GraderError as exc:
        raise RubricError(f"{path.name}: {exc}") from None
