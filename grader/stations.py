"""Station definitions: the true parameters of one lab rig (for simulation and fixtures).

A station file (``reference_solutions/stations/<name>.yaml``) holds the ``given``
block of a manifest, the ``feedback`` convention, the hidden ``truth`` (Kq, Kpot,
β/Vt, Kce, B, leakage …), measurement ``noise`` levels and the rig's unmodelled
``effects``, all as quantity strings.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import yaml
from pydantic import BaseModel, ConfigDict, ValidationError, field_validator

from grader import untrusted
from grader.datasets.schema import Given, number_as_text
from grader.errors import DatasetError, GraderError, SimulationError, validation_message
from grader.model.effects import EffectSet
from grader.model.params import RigParams
from grader.units import quantity_to_float

TRUTH_UNITS: dict[str, str] = {
    "Kq": "in**3/s/mA",
    "Kpot": "V/in",
    "pot_offset": "V",
    "beta_over_Vt": "psi/in**3",
    "Kce": "in**3/s/psi",
    "B": "lbf*s/in",
    "leakage": "in**3/s",
    "null_offset": "mA",
    "flow_saturation": "mA",
}
NOISE_UNITS: dict[str, str] = {"position": "in", "voltage": "V", "flow": "in**3/s", "force": "lbf"}


def repo_root() -> Path:
    """The source checkout holding ``reference_solutions/`` (the package is installed editable)."""
    return Path(__file__).resolve().parents[1]


def reference_dir() -> Path:
    path = repo_root() / "reference_solutions"
    if not path.is_dir():
        raise GraderError(f"{path} not found: install grader from its source checkout with 'pip install -e .'")
    return path


class Station(BaseModel):
    """One station file."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    station: str
    feedback: Literal["volts", "inches"] = "volts"
    given: Given
    truth: dict[str, str]
    noise: dict[str, str] = {}
    effects: dict[str, dict[str, str]] = {}

    @field_validator("truth", "noise", "effects", mode="before")
    @classmethod
    def _numbers_as_text(cls, v: object) -> object:
        """Bare numbers (``4e-4``) as text in the field's unit, as in ``given``."""
        return {k: cls._numbers_as_text(x) for k, x in v.items()} if isinstance(v, dict) else number_as_text(v)

    def truth_values(self) -> dict[str, float]:
        """Truth in internal units; missing optional entries default to 0 (Kq, Kpot, β/Vt, Kce required)."""
        unknown = set(self.truth) - set(TRUTH_UNITS)
        if unknown:
            raise DatasetError(f"station {self.station}: unknown truth field(s) {', '.join(sorted(unknown))}")
        out = {k: 0.0 for k in TRUTH_UNITS}
        out["flow_saturation"] = float("inf")
        for k, v in self.truth.items():
            out[k] = quantity_to_float(v, TRUTH_UNITS[k], where=f"station {self.station}: truth.{k}")
        return out

    def noise_values(self) -> dict[str, float]:
        out = {k: 0.0 for k in NOISE_UNITS}
        for k, v in self.noise.items():
            if k not in NOISE_UNITS:
                raise DatasetError(f"station {self.station}: unknown noise field {k!r}")
            out[k] = quantity_to_float(v, NOISE_UNITS[k], where=f"station {self.station}: noise.{k}")
        return out

    def params(self) -> RigParams:
        """The true linear-model parameters of this station."""
        g, t = self.given.values(), self.truth_values()
        return RigParams(
            A=g["A"], M=g["M"], Kamp=g["Kamp"], Kq=t["Kq"], Kpot=t["Kpot"], beta_over_Vt=t["beta_over_Vt"],
            Kce=t["Kce"], B=t["B"], sample_time=g["sample_time"], feedback=self.feedback,
            supply_pressure=g["supply_pressure"], i_max=g["i_max"],
        )


def station_file(name_or_path: str | Path) -> Path:
    """The file of a station given by name (in ``reference_solutions/stations``) or by path."""
    path = Path(name_or_path)
    return reference_dir() / "stations" / f"{name_or_path}.yaml" if not path.suffix else path


def load_station(name_or_path: str | Path) -> Station:
    """Load a station by name (from ``reference_solutions/stations``) or by file path."""
    path = station_file(name_or_path)
    if not path.is_file():
        raise DatasetError(f"station {name_or_path!s}: no such station file ({path})")
    try:
        raw = untrusted.load_yaml(path.read_text(encoding="utf-8"))
        station = Station.model_validate(raw)
        station.params()
    except yaml.YAMLError as exc:
        raise DatasetError(f"{path.name}: not valid YAML ({str(exc).splitlines()[0]})") from None
    except ValidationError as exc:
        raise DatasetError(validation_message(path.name, exc)) from None
    return station


def station_effects(station: Station) -> EffectSet:
    """The station's own effects (its ``effects:`` block), with its ``noise.position`` as
    ``sensor_noise`` unless the block sets that effect itself."""
    try:
        effects = EffectSet.from_quantities(station.effects)
    except SimulationError as exc:
        raise SimulationError(f"station {station.station}: effects: {exc}") from None
    sigma = station.noise_values()["position"]
    if "sensor_noise" not in effects and sigma > 0:
        effects = effects.merged(EffectSet({"sensor_noise": {"sigma": sigma}}))
    return effects
