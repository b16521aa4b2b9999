"""The output-path policy shared by every verb (checked before any work starts).

* missing parent folders are created;
* where a file is expected, an existing folder is an error naming the path (and the reverse);
* a file standing where a folder is needed, or a folder that cannot be written, is an error;
* writers are atomic (:mod:`grader.exports.atomic`): no temporary file is left behind;
* a folder a verb created and left empty because it failed is removed (:func:`discard_empty_created`).

Each problem is an :class:`grader.errors.OutputPathError` with a one-line message, which the
CLI prints as ``grader VERB: error: …`` with exit code 2.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from grader.errors import OutputPathError

_CREATED: list[Path] = []  # folders created by this process since the last discard


def _blocking_file(path: Path) -> Path | None:
    """The first ancestor of ``path`` that exists but is not a folder, if any."""
    for parent in reversed(path.parents):
        if parent.exists() and not parent.is_dir():
            return parent
    return None


def _make_folder(folder: Path, target: Path) -> None:
    """Create ``folder`` (and its parents) and prove it writable with a probe file removed at once."""
    blocker = _blocking_file(folder / "x")
    if blocker is not None:
        raise OutputPathError(f"{target}: {blocker} is a file, not a folder; choose another output path")
    missing = [p for p in (folder, *folder.parents) if not p.exists()]
    try:
        folder.mkdir(parents=True, exist_ok=True)
        _CREATED.extend(missing)
        fd, probe = tempfile.mkstemp(prefix=".grader-probe-", dir=folder)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise OutputPathError(f"{target}: cannot write in folder {folder} ({exc.strerror or exc})") from None


def output_file(path: str | os.PathLike[str], *, example: str = "out.json") -> Path:
    """Make ``path`` ready to receive a file; ``example`` is a file name suggested when it is a folder."""
    path = Path(path)
    if path.is_dir():
        raise OutputPathError(f"{path}: is a folder, but a file is expected here (for example {path / example})")
    _make_folder(path.parent, path)
    return path


def output_folder(path: str | os.PathLike[str]) -> Path:
    """Make ``path`` an existing, writable folder (created with its parents if missing)."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise OutputPathError(f"{path}: is a file, but a folder is expected here; choose another output path")
    _make_folder(path, path)
    return path


def write_bytes(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (temporary file + rename; the temporary file never stays)."""
    path = output_file(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as exc:
        raise OutputPathError(f"{path}: cannot write ({exc.strerror or exc})") from None
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        raise OutputPathError(f"{path}: cannot write ({exc.strerror or exc})") from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def write_text(path: str | os.PathLike[str], text: str) -> Path:
    """Write UTF-8 ``text`` to ``path`` atomically."""
    return write_bytes(path, text.encode("utf-8"))


def discard_empty_created(*, failed: bool) -> None:
    """Forget the folders this process created; after a verb that ``failed``, first remove those still empty
    (deepest first, so a created parent left empty by its removed child goes too)."""
    created = sorted(set(_CREATED), key=lambda p: len(p.parts), reverse=True)
    _CREATED.clear()
    for folder in created if failed else ():
        try:
            folder.rmdir()  # only an empty folder goes
        except OSError:
            pass
