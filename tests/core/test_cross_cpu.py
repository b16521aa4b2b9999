"""Cross-CPU determinism: ``grader key`` writes the same bytes whatever BLAS kernels run.

OpenBLAS picks its kernels by CPU; ``OPENBLAS_CORETYPE`` forces the kernels of an older
or newer CPU, so one machine can stand in for three.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from grader.stations import reference_dir

CORE_TYPES = ("Prescott", "Nehalem", "Haswell")


def _key_bytes(core: str, out: Path) -> bytes:
    env = {**os.environ, "OPENBLAS_CORETYPE": core}
    code = "from grader.cli import main; import sys; sys.exit(main(sys.argv[1:]))"
    subprocess.run([sys.executable, "-c", code, "key", str(reference_dir() / "datasets" / "default"), "-o", str(out)],
                   env=env, check=True, capture_output=True, timeout=300)
    return out.read_bytes()


def test_key_bytes_are_the_same_under_every_blas_core_type(tmp_path: Path) -> None:
    written = {core: _key_bytes(core, tmp_path / f"{core}.json") for core in CORE_TYPES}
    checked_in = (reference_dir() / "keys" / "default.json").read_bytes()
    for core, data in written.items():
        assert data == checked_in, f"OPENBLAS_CORETYPE={core} wrote a key different from the checked-in one"
