"""Load, validate, hash and write lab datasets (a folder: manifest + CSV files)."""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from pydantic import ValidationError

from grader import untrusted
from grader.datasets.csvio import Table, read_rows, read_table, write_table
from grader.datasets.sampling import check_rows
from grader.datasets.schema import CALIBRATION, FLOW_TEST, FRICTION, RUN, Manifest, RunSpec
from grader.errors import DatasetError, GraderError, validation_message
from grader.model.params import Controller

MANIFEST_NAMES = ("manifest.json", "manifest.yaml", "manifest.yml")
MAX_MANIFEST_BYTES = 1_000_000


@dataclass(frozen=True)
class Run:
    """One closed-loop run in internal units: t [s], r and y [in], u [V] or None."""

    spec: RunSpec
    t: NDArray[np.float64]
    r: NDArray[np.float64]
    y: NDArray[np.float64]
    u: NDArray[np.float64] | None = None
    lines: NDArray[np.int64] | None = None  # each row's line in its file (None: row k on line k + 2)

    @property
    def name(self) -> str:
        return self.spec.name

    def line(self, k: int) -> int:
        """The file line (1-based) of row ``k`` (0-based) of the run as read."""
        return int(self.lines[k]) if self.lines is not None else k + 2

    @property
    def controller(self) -> Controller:
        c = self.spec.controller
        return Controller(Kp=c.Kp, Ki=c.Ki, Kd=c.Kd)


@dataclass(frozen=True)
class Dataset:
    """A validated lab dataset with tables converted to internal units."""

    root: Path
    manifest: Manifest
    given: dict[str, float]
    calibration: Table | None
    flow_test: Table | None
    friction: Table | None
    runs: tuple[Run, ...] = field(default_factory=tuple)
    inputs_sha256: str = ""

    def runs_of(self, kind: str) -> tuple[Run, ...]:
        return tuple(r for r in self.runs if r.spec.kind == kind)



def _read_raw(path: Path) -> dict:
    """The manifest file's content, parsed but not validated."""
    if path.is_symlink():
        raise DatasetError(f"{path.name}: is a symbolic link; the manifest must be a regular file")
    if path.stat().st_size > MAX_MANIFEST_BYTES:
        raise DatasetError(f"{path.name}: manifest larger than 1 MB")
    try:
        text = path.read_text(encoding="utf-8-sig")  # a byte-order mark (Windows editors) is not content
    except UnicodeDecodeError:
        raise DatasetError(f"{path.name}: not UTF-8 text") from None
    try:
        raw = untrusted.parse(path.name, text, as_json=path.suffix == ".json")
    except GraderError as exc:
        raise DatasetError(str(exc)) from None
    if not isinstance(raw, dict):
        raise DatasetError(f"{path.name}: must hold a mapping (object) at the top level")
    return raw


def _same_meaning(a: dict, b: dict) -> bool:
    """Whether two valid manifests say the same in other words: their fields with defaults filled in, and the given
    values in internal units (``2.53 ms`` is ``0.00253 s``; a weight is the mass it implies)."""
    try:
        ma, mb = Manifest.model_validate(a), Manifest.model_validate(b)
        va, vb = ma.given.values(), mb.given.values()
    except (ValidationError, GraderError):
        return False
    return (ma.model_dump(exclude={"given"}) == mb.model_dump(exclude={"given"}) and va.keys() == vb.keys()
            and all(math.isclose(va[k], vb[k], rel_tol=1e-9) for k in va))


def read_manifest(root: Path) -> tuple[Manifest, Path]:
    """Find and validate the manifest in ``root``. Two manifests (say a JSON one and the YAML it was written
    from) must say the same, in any words (:func:`_same_meaning`); the first of :data:`MANIFEST_NAMES` is the one
    read."""
    if not root.is_dir():
        raise DatasetError(f"{root}: not a dataset folder")
    paths = [root / n for n in MANIFEST_NAMES if (root / n).is_file()]
    if not paths:
        raise DatasetError(f"{root}: no manifest.json or manifest.yaml")
    path, raw = paths[0], _read_raw(paths[0])
    for other in paths[1:]:
        if (second := _read_raw(other)) != raw and not _same_meaning(raw, second):
            key = next((k for k in sorted({*raw, *second}, key=str) if (k in raw) != (k in second)
                        or raw.get(k) != second.get(k)), "?")
            raise DatasetError(f"{path.name} and {other.name} are both in the folder and say different things "
                               f"(first in {key!r}); keep the one that describes the data")
    try:
        return Manifest.model_validate(raw), path
    except ValidationError as exc:
        raise DatasetError(validation_message(path.name, exc)) from None
    except GraderError as exc:
        raise DatasetError(f"{path.name}: {exc}") from None


def _check_run(run: Run) -> None:
    name = run.spec.file
    dt = np.diff(run.t)
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        raise DatasetError(f"{name}: time is not strictly increasing at row {run.line(int(bad[0]) + 1)}")


def _hash(root: Path, manifest_path: Path, files: list[str]) -> str:
    h = hashlib.sha256()
    for name in [manifest_path.name, *sorted(set(files))]:
        h.update(name.encode() + b"\0" + (root / name).read_bytes().replace(b"\r\n", b"\n") + b"\0")
    return h.hexdigest()


def load(root: str | Path) -> Dataset:
    """Load and validate the dataset in folder ``root``."""
    root = Path(root)
    manifest, manifest_path = read_manifest(root)
    try:
        given = manifest.given.values()
    except GraderError as exc:
        raise DatasetError(f"{manifest_path.name}: {exc}") from None
    tables = {
        key: read_table(root / name, spec) if name else None
        for key, name, spec in (
            ("calibration", manifest.calibration, CALIBRATION),
            ("flow_test", manifest.flow_test, FLOW_TEST),
            ("friction", manifest.friction, FRICTION),
        )
    }
    runs = []
    for spec in manifest.runs:
        table, lines = read_rows(root / spec.file, RUN)
        run = Run(spec=spec, t=table["t"], r=table["r"], y=table["y"], u=table.get("u"), lines=lines)
        _check_run(run)
        check_rows(run, given["sample_time"])  # one row per controller sample
        runs.append(run)
    files = [n for n in (manifest.calibration, manifest.flow_test, manifest.friction) if n]
    files += [r.file for r in manifest.runs]
    return Dataset(root, manifest, given, runs=tuple(runs), inputs_sha256=_hash(root, manifest_path, files), **tables)


def write_dataset(root: str | Path, manifest: Manifest, tables: dict[str, dict[str, tuple[str, NDArray[np.float64]]]]) -> Path:
    """Write ``manifest.json`` and each ``{file name: {column: (unit, values)}}`` table into ``root``."""
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    for name, columns in sorted(tables.items()):
        write_table(root / name, columns)
    text = json.dumps(manifest.model_dump(mode="json", exclude_none=True), indent=2) + "\n"
    (root / "manifest.json").write_text(text, encoding="utf-8")
    return root
