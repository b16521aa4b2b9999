"""What a submission is graded against: the key, the dataset it came from, and the station.

:class:`KeyStore` resolves and caches keys: a submission carrying its group's own data
is graded against a key built from that data; otherwise against its station's dataset
(``reference_solutions/datasets/<station>/``), whose key is read from
``reference_solutions/keys/<station>.json`` when that file's ``inputs_sha256`` matches
the dataset, and built otherwise. Keys are cached by the dataset's inputs hash in memory
and, with ``cache_dir``, on disk (``<cache_dir>/<inputs_sha256>.json``).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from grader.datasets import Dataset, load
from grader.errors import GraderError, KeyFileError, SubmissionError
from grader.keys import Key, build_key, read_key, write_key
from grader.model.params import RigParams
from grader.stations import reference_dir

_STATION = re.compile(r"^[A-Za-z0-9_.\-]{1,64}$")


@dataclass(frozen=True)
class KeyContext:
    """A key with the dataset it was computed from (internal units throughout).

    ``memo`` caches values derived from the key (known mistakes' values), per process.
    """

    key: Key
    dataset: Dataset
    source: str  # "station" or "group data"
    memo: dict[Any, Any] = field(default_factory=dict, compare=False, hash=False, repr=False)

    @property
    def given(self) -> Mapping[str, float]:
        """bore, rod [in], A [in²], M [lbf·s²/in], Kamp [mA/V], sample_time [s], …"""
        return self.dataset.given

    @property
    def k_fb(self) -> float:
        """Kpot [V/in] in the volts convention, else 1."""
        return self.key.value("Kpot") if self.key.feedback == "volts" else 1.0

    def value(self, name: str) -> Any:
        return self.key.quantities[name].value

    def unit(self, name: str) -> str:
        return self.key.quantities[name].unit

    def params(self) -> RigParams:
        """The identified (sampled-loop refined) model."""
        return self.key.params()

    def matching_inputs(self) -> dict[str, float]:
        """The inputs of the students' coefficient matching (ω, Kp_crit, Kq, Kpot, A, M, Kamp, B); KeyFileError where
        the key has none (β/Vt not identifiable: no critical oscillation, or no Kq)."""
        entry = self.key.quantities["beta_over_Vt"]
        if entry.value is None or not entry.inputs:
            raise KeyFileError(f"the key's beta_over_Vt has no coefficient matching to redo ({entry.reason})")
        e = entry.inputs
        return {"omega": e["omega_crit [rad/s]"], "kp_crit": e["Kp_crit"], "Kq": e["Kq [in^3/s/mA]"],
                "Kpot": e["Kpot [V/in]"], "A": e["A [in^2]"], "M": e["M [lbf*s^2/in]"], "Kamp": e["Kamp [mA/V]"],
                "B": e["B [lbf*s/in]"]}


@dataclass
class KeyStore:
    """Resolves and caches the key for a station or a group's own dataset (not shared between processes)."""

    datasets_dir: Path | None = None
    keys_dir: Path | None = None
    cache_dir: Path | None = None
    _cache: dict[str, KeyContext] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        if self.datasets_dir is None or self.keys_dir is None:
            ref = reference_dir()
            self.datasets_dir = self.datasets_dir or ref / "datasets"
            self.keys_dir = self.keys_dir or ref / "keys"

    def stations(self) -> list[str]:
        assert self.datasets_dir is not None
        return sorted(p.name for p in self.datasets_dir.iterdir() if p.is_dir()) if self.datasets_dir.is_dir() else []

    def for_station(self, station: str) -> KeyContext:
        """The key of a station's dataset; an unknown station is the submission's error."""
        assert self.datasets_dir is not None
        if not isinstance(station, str) or not _STATION.match(station) or not (self.datasets_dir / station).is_dir():
            known = ", ".join(self.stations()) or "none installed"
            raise SubmissionError(f"unknown station {str(station)[:64]!r} (known: {known})")
        return self._context(self.datasets_dir / station, "station")

    def for_dataset(self, root: Path) -> KeyContext:
        """The key of a group's own dataset; a dataset that cannot be read is the submission's error."""
        try:
            return self._context(root, "group data")
        except GraderError as exc:
            raise SubmissionError(f"your data ({root.name}): {exc}") from None

    def add(self, ctx: KeyContext) -> None:
        """Seed the cache (keys resolved in another process)."""
        self._cache[ctx.dataset.inputs_sha256] = ctx

    def _context(self, root: Path, source: str) -> KeyContext:
        dataset = load(root)
        cached = self._cache.get(dataset.inputs_sha256)
        if cached is not None:
            return cached
        key = (self._checked_in(dataset) if source == "station" else None) or self._cached(dataset)
        if key is None:
            key = build_key(dataset)
            if self.cache_dir is not None:
                write_key(key, _mkdir(self.cache_dir) / f"{dataset.inputs_sha256}.json")
        ctx = KeyContext(key=key, dataset=dataset, source=source)
        self._cache[dataset.inputs_sha256] = ctx
        return ctx

    def _checked_in(self, dataset: Dataset) -> Key | None:
        assert self.keys_dir is not None
        return _matching_key(self.keys_dir / f"{dataset.root.name}.json", dataset)

    def _cached(self, dataset: Dataset) -> Key | None:
        return _matching_key(self.cache_dir / f"{dataset.inputs_sha256}.json", dataset) if self.cache_dir else None


def _mkdir(path: Path) -> Path:
    path.mkdir(parents=True, exist_ok=True)
    return path


def _matching_key(path: Path, dataset: Dataset) -> Key | None:
    """The key in ``path`` if it exists, reads, and was computed from ``dataset``."""
    if not path.is_file():
        return None
    try:
        key = read_key(path)
    except KeyFileError:
        return None
    return key if key.inputs_sha256 == dataset.inputs_sha256 else None
