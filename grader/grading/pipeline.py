"""Batch grading: find files, read them, resolve keys, run rig checks, grade (in parallel), in order.

PrairieLearn style: a submission that cannot be read is a result (``valid`` False, every
item ``invalid``, the reason as feedback), never a crash; one bad submission never stops a
batch. Keys are resolved in the parent (built in parallel when groups bring their own data),
rig simulations are batched across all designs, and grading runs in a process pool whose
workers receive the keys once (pool initializer). Results come back in input order.
"""

from __future__ import annotations

import glob
import json
import multiprocessing as mp
import tempfile
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from grader.errors import GraderError, SubmissionError
from grader.grading.answers import AnswerError, read_design
from grader.grading.context import KeyContext, KeyStore
from grader.grading.designs import RigCase, RigVerdict, rig_verdicts
from grader.grading.grade import GradeOptions, check_rubric_units, grade_submission, invalid_submission
from grader.grading.results import SubmissionResult
from grader.grading.submissions import SUFFIXES, InlineData, Submission, fallback_id, read_submission, students_hint
from grader.stations import load_station
from grader.units import quantity_to_float

Read = Submission | SubmissionResult  # a read submission, or the invalid result of one that could not be read


def _matches(text: str) -> list[Path]:
    """What one input names: its glob's matches, or the path itself."""
    return [Path(m) for m in sorted(glob.glob(text, recursive=True))] if any(c in text for c in "*?[") else [Path(text)]


def passed_over(inputs: Sequence[str]) -> list[Path]:
    """Files in the folders among ``inputs`` that :func:`expand_inputs` leaves out: not a submission type (hidden
    files aside), so that a batch can say which were not graded (a group's ``.ods`` or ``.xls``)."""
    out = {f for text in inputs for m in _matches(text) if m.is_dir() for f in m.iterdir()
           if f.is_file() and f.suffix.lower() not in SUFFIXES and not f.name.startswith(".")}
    return sorted(out, key=lambda f: (str(f.parent), f.name))


def expand_inputs(inputs: Sequence[str]) -> list[Path]:
    """Files, folders (their submission files, not recursive) and globs -> sorted unique files."""
    found: set[Path] = set()
    for text in inputs:
        matches = _matches(text)
        if not matches:
            raise SubmissionError(f"{text}: no file matches")
        for m in matches:
            if m.is_dir():
                found.update(f for f in m.iterdir() if f.is_file() and f.suffix.lower() in SUFFIXES)
            elif m.is_file():
                found.add(m)
            else:
                raise SubmissionError(f"{text}: no such file or folder")
    return sorted(found, key=lambda f: (str(f.parent), f.name))


def read_all(paths: Sequence[Path], opts: GradeOptions) -> list[Read]:
    """Read every file; unreadable ones and duplicate ids become invalid results."""
    out: list[Read] = []
    seen: dict[str, Path] = {}
    for path in paths:
        try:
            sub: Read = read_submission(path, limits=opts.limits)
        except GraderError as exc:
            sub = invalid_submission(fallback_id(path), str(path), str(exc), opts.rubric, students_hint(path))
        except Exception as exc:  # noqa: BLE001 - a safety net: nothing is silently dropped
            error = f"internal error reading it ({type(exc).__name__})"
            sub = invalid_submission(fallback_id(path), str(path), error, opts.rubric)
        sid = sub.submission_id
        if sid.casefold() in seen:  # case-insensitively: output file names must not collide on any OS
            unique = next(f"{sid}~{n}" for n in range(2, len(paths) + 2) if f"{sid}~{n}".casefold() not in seen)
            own = sub.error if isinstance(sub, SubmissionResult) else None  # unreadable: its own error, not the
            # collision of two ids made from file names (ä.json and -.json are both 'submission')
            error = own or f"duplicate submission_id {sid!r} (also in {seen[sid.casefold()].name}); rename one"
            sub = invalid_submission(unique, str(path), error, opts.rubric, sub.students)
            sid = unique
        seen[sid.casefold()] = path
        out.append(sub)
    return out


def _inline_dataset(sub: Submission, data: InlineData, root: Path) -> Path:
    """Write a group's sheets as a dataset folder (given and feedback from the station file)."""
    station = load_station(sub.station)
    root.mkdir(parents=True, exist_ok=True)
    for name, text in data.files.items():
        (root / name).write_text(text, encoding="utf-8")
    manifest = {"station": station.station, "given": station.given.model_dump(exclude_none=True),
                "feedback": station.feedback, "runs": data.runs,
                **{k: f for k, f in (("calibration", "calibration.csv"), ("flow_test", "flow.csv"),
                                     ("friction", "friction.csv")) if f in data.files}}
    (root / "manifest.json").write_text(json.dumps(manifest), encoding="utf-8")
    return root


def resolve_key(sub: Submission, store: KeyStore) -> KeyContext:
    """The key ``sub`` is graded against (its own data if it has any, else its station's)."""
    if isinstance(sub.data, Path):
        return store.for_dataset(sub.data)
    if isinstance(sub.data, InlineData):
        with tempfile.TemporaryDirectory() as tmp:
            try:
                root = _inline_dataset(sub, sub.data, Path(tmp) / f"{sub.submission_id}-data")
            except GraderError as exc:
                raise SubmissionError(f"your data sheets: {exc}") from None
            return store.for_dataset(root)
    return store.for_station(sub.station)


def _key_job(args: tuple[Submission, KeyStore]) -> KeyContext | str:
    sub, store = args
    try:
        return resolve_key(sub, store)
    except GraderError as exc:
        return str(exc)
    except Exception as exc:  # noqa: BLE001 - odd group data must not stop the batch
        return f"internal error computing the key from the lab data ({type(exc).__name__}: {exc})"


def _source_of(sub: Submission) -> Any:
    return str(sub.data) if isinstance(sub.data, Path) else (id(sub) if sub.data is not None else f"station:{sub.station}")


def resolve_keys(subs: list[Read], store: KeyStore, *, workers: int) -> list[KeyContext | str | None]:
    """One key per submission (an error message when it has none); distinct sources built in parallel."""
    todo: dict[Any, Submission] = {}
    for s in subs:
        if isinstance(s, Submission):
            todo.setdefault(_source_of(s), s)
    jobs = [(s, store) for s in todo.values()]
    if workers > 1 and len(jobs) > 1:
        with mp.get_context("fork").Pool(min(workers, len(jobs))) as pool:
            done = pool.map(_key_job, jobs)
    else:
        done = [_key_job(j) for j in jobs]
    by_source = dict(zip(todo, done))
    for ctx in done:
        if isinstance(ctx, KeyContext):
            store.add(ctx)
    return [by_source[_source_of(s)] if isinstance(s, Submission) else None for s in subs]


def _rig_chunk(args: tuple[list[RigCase], float]) -> dict[RigCase, RigVerdict | None]:
    return rig_verdicts(args[0], threshold=args[1])


def rig_prepass(subs: list[Read], keys: list[KeyContext | str | None], opts: GradeOptions, *,
                workers: int = 1) -> dict[RigCase, RigVerdict | None]:
    """Batched rig verdicts for every readable design that is stable on its model (split over workers)."""
    from grader.model import zloop

    out: dict[RigCase, RigVerdict | None] = {}
    for item, spec in ((n, i.design) for n, i in opts.rubric.items.items() if i.design is not None):
        cases = []
        for sub, kc in zip(subs, keys):
            if not (isinstance(sub, Submission) and isinstance(kc, KeyContext)) or sub.answers.get(item) is None:
                continue
            try:
                ans = read_design(sub.answers[item], item=item, gain_unit=kc.unit("Kp_crit"))
            except (AnswerError, GraderError, TypeError):
                continue
            if kc.key.identified and zloop.is_stable(kc.params(), ans.gains):
                cases.append(RigCase(kc.key.station, item, ans.gains))
        unique = sorted(set(cases), key=lambda c: (c.station, c.gains.Kp, c.gains.Ki, c.gains.Kd))
        threshold = quantity_to_float(spec.limit_cycle, "in")
        n = workers if len(unique) > 64 else 1
        chunks = [(unique[i::n], threshold) for i in range(n)]
        if len(chunks) > 1:
            with mp.get_context("fork").Pool(workers) as pool:
                parts = pool.map(_rig_chunk, chunks)
        else:
            parts = [_rig_chunk(chunks[0])]
        for part in parts:
            out.update(part)
    return out


@dataclass(frozen=True)
class _Shared:
    opts: GradeOptions
    keys: dict[str, KeyContext]
    rig: dict[RigCase, RigVerdict | None]


_WORKER: dict[str, _Shared] = {}  # per-process state installed by the pool initializer (read-only afterwards)
KeyRef = tuple[str, str] | None  # ("key", inputs sha256) or ("error", message)


def _init_worker(shared: _Shared) -> None:
    _WORKER["shared"] = shared


def _grade_job(job: tuple[Read, KeyRef]) -> SubmissionResult:
    sub, ref = job
    return _grade_one(sub, ref, _WORKER["shared"])


def _grade_one(sub: Read, ref: KeyRef, shared: _Shared) -> SubmissionResult:
    if isinstance(sub, SubmissionResult):
        return sub
    if ref is None or ref[0] == "error":
        error = ref[1] if ref else "no key"
        return invalid_submission(sub.submission_id, str(sub.source), error, shared.opts.rubric, sub.students)
    try:
        return grade_submission(sub, shared.keys[ref[1]], shared.opts, rig=shared.rig)
    except Exception as exc:  # noqa: BLE001 - a safety net: one submission never stops a batch
        error = f"internal error while grading ({type(exc).__name__}: {exc})"
        return invalid_submission(sub.submission_id, str(sub.source), error, shared.opts.rubric, sub.students)


def _ref(k: KeyContext | str | None) -> KeyRef:
    if isinstance(k, KeyContext):
        return ("key", k.dataset.inputs_sha256)
    return ("error", k) if isinstance(k, str) else None


def grade_batch(subs: list[Read], opts: GradeOptions, store: KeyStore, *, workers: int = 2,
                on_stage: Callable[[str], None] | None = None) -> Iterator[SubmissionResult]:
    """Grade every read submission; yields results in input order."""
    stage = on_stage or (lambda s: None)
    stage("resolving keys")
    keys = resolve_keys(subs, store, workers=workers)
    ctxs = {k.dataset.inputs_sha256: k for k in keys if isinstance(k, KeyContext)}
    for kc in ctxs.values():
        check_rubric_units(opts.rubric, kc)
    stage("rig simulations")
    shared = _Shared(opts, ctxs, rig_prepass(subs, keys, opts, workers=workers))
    stage("grading")
    jobs = [(s, _ref(k)) for s, k in zip(subs, keys)]
    if workers <= 1 or len(jobs) < 16:
        for sub, ref in jobs:
            yield _grade_one(sub, ref, shared)
        return
    with mp.get_context("fork").Pool(workers, initializer=_init_worker, initargs=(shared,)) as pool:
        yield from pool.imap(_grade_job, jobs, chunksize=max(1, len(jobs) // (workers * 8)))
