"""Answer keys: every quantity the grader checks, computed from one lab dataset.

A key is JSON (schema :class:`Key`): ``quantities`` maps canonical item names to
``{"value", "unit", "interval", "method", "inputs", "status", "reason", "note"}``;
``model`` holds the identified linear model used for simulation and design checks;
``inputs_sha256`` and ``generated_by`` record what produced it. An item the identified rig
cannot have has ``status: "not_reachable"``, a null value and interval, and a ``reason``; an item
the data cannot give (an instability run without the loop's critical oscillation) has ``status:
"not_identifiable"`` likewise, and then the model's ``beta_over_Vt`` and ``Kce`` are null.
Numbers are written at :data:`grader.precision.SIGNIFICANT_DIGITS` significant digits, so
the same inputs give byte-identical files on every CPU. Keys written before ``status``,
``reason`` and ``note`` existed still load (they default to ``"ok"``, null, null).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from grader import __version__
from grader.datasets import Dataset, load
from grader.errors import KeyFileError, validation_message
from grader.model.params import RigParams
from grader.outpaths import write_text
from grader.precision import round_group, round_sig, rounded

if TYPE_CHECKING:  # the identification (scipy, python-control) is imported only to build a key
    from grader.identify import Estimate, Identification

SCHEMA = "grader.key/1"
#: RigParams field -> unit written in the key's ``model`` block
MODEL_UNITS: dict[str, str] = {
    "A": "in**2", "M": "lbf*s**2/in", "Kamp": "mA/V", "Kq": "in**3/s/mA", "Kpot": "V/in",
    "beta_over_Vt": "psi/in**3", "Kce": "in**3/s/psi", "B": "lbf*s/in", "sample_time": "s",
    "supply_pressure": "psi", "i_max": "mA",
}


class KeyEntry(BaseModel):
    """One key quantity. ``interval`` is the 95 % interval (null for structured values and
    not-reachable items); ``status`` ``not_reachable`` means the identified rig has no such
    value, ``not_identifiable`` that the data cannot give it (``value`` null, ``reason`` says
    why); ``note`` flags e.g. a value clipped at a bound."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    value: Any
    unit: str
    interval: tuple[float, float] | None
    method: str
    inputs: dict[str, Any]
    status: Literal["ok", "not_reachable", "not_identifiable"] = "ok"
    reason: str | None = None
    note: str | None = None

    @property
    def reachable(self) -> bool:
        return self.status == "ok"


class ModelBlock(BaseModel):
    """The identified linear model, in the units of :data:`MODEL_UNITS` (``beta_over_Vt`` and
    ``Kce`` null when the dataset cannot give them; ``Kq`` too when the flow test cannot)."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    A: float = Field(gt=0)
    M: float = Field(gt=0)
    Kamp: float = Field(gt=0)
    Kq: float | None = Field(gt=0)
    Kpot: float = Field(gt=0)
    beta_over_Vt: float | None = Field(gt=0)
    Kce: float | None = Field(ge=0)
    B: float = Field(ge=0)
    sample_time: float = Field(gt=0)
    supply_pressure: float = Field(gt=0)
    i_max: float = Field(gt=0)


class Key(BaseModel):
    """An answer key file."""

    model_config = ConfigDict(extra="forbid", frozen=True, populate_by_name=True)
    schema_: Literal["grader.key/1"] = Field(default=SCHEMA, alias="schema")
    station: str
    dataset: str
    feedback: Literal["volts", "inches"]
    generated_by: dict[str, str]
    inputs_sha256: str
    model: ModelBlock
    model_units: dict[str, str] = Field(default_factory=lambda: dict(MODEL_UNITS))
    quantities: dict[str, KeyEntry]

    def params(self) -> RigParams:
        """The identified linear model (KeyFileError when the data could not give β/Vt and Kce)."""
        m = self.model
        if m.beta_over_Vt is None or m.Kce is None or m.Kq is None:
            why = self.quantities["Kce"].reason if "Kce" in self.quantities else None
            raise KeyFileError(f"key for {self.station}: the model is not identifiable ({why or 'β/Vt and Kce are null'})")
        return RigParams(A=m.A, M=m.M, Kamp=m.Kamp, Kq=m.Kq, Kpot=m.Kpot, beta_over_Vt=m.beta_over_Vt, Kce=m.Kce,
                         B=m.B, sample_time=m.sample_time, feedback=self.feedback,
                         supply_pressure=m.supply_pressure, i_max=m.i_max)

    @property
    def identified(self) -> bool:
        """Whether the data gave the model's Kq, β/Vt and Kce (else :meth:`params` raises)."""
        return self.model.beta_over_Vt is not None and self.model.Kce is not None and self.model.Kq is not None

    def value(self, item: str) -> Any:
        return self.quantities[item].value


def _entry(e: Estimate) -> KeyEntry:
    inputs = rounded(dict(e.inputs))
    if e.status != "ok":
        return KeyEntry(value=None, unit=e.unit, interval=None, method=e.method, inputs=inputs,
                        status=e.status, reason=e.reason)
    lo, hi = e.interval
    return KeyEntry(value=round_sig(e.value), unit=e.unit, interval=(round_sig(lo), round_sig(hi)), method=e.method,
                    inputs=inputs, note=e.note)


def _poles_entry(ident: Identification) -> KeyEntry:
    from grader.model.linear import closed_loop_poles

    method = "roots of the continuous characteristic polynomial of the students' identified model, per run"
    if ident.students_params is None:
        return KeyEntry(value=None, unit="1/s", interval=None, inputs={}, method=method, status="not_identifiable",
                        reason=f"needs β/Vt and Kce, which the data do not give: {ident.estimates['Kce'].reason}")
    runs = []
    for run in ident.dataset.runs:
        poles = closed_loop_poles(ident.students_params, run.controller)
        runs.append({"run": run.name, "Kp": run.controller.Kp, "Ki": run.controller.Ki, "Kd": run.controller.Kd,
                     "poles": [round_group([p.real, p.imag]) for p in poles]})
    return KeyEntry(value=runs, unit="1/s", interval=None, inputs={}, method=method)


def _model_values(ident: Identification) -> dict[str, float | None]:
    """The model block's values: the refined model's, or without one the measured parts (β/Vt, Kce null)."""
    if ident.params is not None:
        return {name: round_sig(getattr(ident.params, name)) for name in MODEL_UNITS}
    g, e = ident.dataset.given, ident.estimates
    known = {**{k: g[k] for k in ("A", "M", "Kamp", "sample_time", "supply_pressure", "i_max")},
             "Kq": e["Kq"].value, "Kpot": e["Kpot"].value, "B": ident.match_B}
    return {name: round_sig(known[name]) if name in known and np.isfinite(known[name]) else None
            for name in MODEL_UNITS}


def build_key(dataset: Dataset) -> Key:
    """Identify the model from ``dataset`` and assemble its key."""
    from grader.identify import identify, predictions

    ident = identify(dataset)
    quantities = {name: _entry(e) for name, e in {**ident.estimates, **predictions(ident)}.items()}
    quantities["closed_loop_poles"] = _poles_entry(ident)
    model = ModelBlock(**_model_values(ident))
    return Key(
        station=dataset.manifest.station, dataset=dataset.root.name, feedback=dataset.manifest.feedback,
        generated_by={"package": "grader", "version": __version__}, inputs_sha256=dataset.inputs_sha256,
        model=model, quantities=dict(sorted(quantities.items())),
    )


def key_json(key: Key) -> str:
    """Canonical JSON text of ``key`` (sorted keys, two-space indent, trailing newline,
    numbers at :data:`~grader.precision.SIGNIFICANT_DIGITS` significant digits)."""
    data = rounded(key.model_dump(mode="json", by_alias=True))
    return json.dumps(data, indent=2, sort_keys=True, ensure_ascii=False) + "\n"


def write_key(key: Key, path: str | Path) -> Path:
    """Write ``key`` atomically (creating missing parent folders)."""
    return write_text(path, key_json(key))


def read_key(path: str | Path) -> Key:
    """Read and validate a key file."""
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise KeyFileError(f"{path}: key file not found") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise KeyFileError(f"{path.name}: not valid JSON ({exc})") from None
    if not isinstance(data, dict) or data.get("schema") != SCHEMA:
        raise KeyFileError(f"{path.name}: not a grader key (schema must be {SCHEMA!r})")
    try:
        return Key.model_validate(data)
    except ValidationError as exc:
        raise KeyFileError(validation_message(path.name, exc)) from None


def key_for_dataset(root: str | Path) -> Key:
    """Load the dataset in ``root`` and build its key."""
    return build_key(load(root))
