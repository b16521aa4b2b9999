"""What the web server does with a submission: read it, check it key-safely, and say how an answer is read.

:class:`CheckService` holds the rubric, the station keys (resolved once, kept in memory)
and a bounded memo of rig verdicts of designs, and calls the same
:func:`~grader.grading.selfcheck.self_check` as ``grader check``, so the page, the API and
the command line give the same statuses and feedback. Nothing here returns a key value.
"""

from __future__ import annotations

import tempfile
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from grader.errors import GraderError, SubmissionError
from grader.grading.context import KeyContext, KeyStore
from grader.grading.designs import RigCase, RigVerdict
from grader.grading.grade import GradeOptions
from grader.grading.results import SubmissionResult
from grader.grading.selfcheck import self_check
from grader.grading.submissions import Submission, fallback_id, from_mapping, read_submission

#: Filled in when a JSON document leaves them out (the API makes them optional).
DOC_DEFAULTS: dict[str, Any] = {"submission_id": "self-check", "students": [{"name": "student"}]}
RIG_MEMO_SIZE = 4096  # rig verdicts kept (one per distinct station, design item and gains)
RIG_WAIT_S = 60.0  # longest wait for another thread's rig simulation of the same design
#: A submission checked once per station at start-up, so that no student's check pays the imports,
#: the compiled engine's loading or a key's first use (wrong or right does not matter: nothing is sent).
WARM_ANSWERS: dict[str, Any] = {
    "closed_loop_tf": "4 beta A Kp Kamp Kpot Kq / (M Vt s^3 + (B Vt + 4 beta Kce M) s^2 + 4 beta (A^2 + B Kce) s"
                      " + 4 beta A Kp Kamp Kpot Kq)",
    "open_loop_tf": "4 beta A Kp Kamp Kpot Kq / (s (M Vt s^2 + (B Vt + 4 beta Kce M) s + 4 beta (A^2 + B Kce)))",
    "char_poly": "s^3 + (B/M + 4 beta Kce/Vt) s^2 + 4 beta (A^2 + B Kce)/(M Vt) s + 4 beta A Kp Kamp Kpot Kq/(M Vt) = 0",
    "Kpot": "1 V/in", "Kq": "0.04 in^3/s/mA", "omega_crit": "25 Hz", "Kp_crit": 50, "Kce": "5e-4 in^3/s/psi",
    "beta_over_Vt": "3e4 psi/in^3", "Kp_no_overshoot": 20, "Kp_25_overshoot": 40, "ramp_ess_P": "0.1 in",
    "closed_loop_poles": [{"Kp": 10, "Ki": 0, "Kd": 0, "poles": ["-20+150j", "-20-150j", "-10"]}],
    "pd_design": {"Kp": 40, "Kd": 0.1, "overshoot": "10 %"},
    "pi_design": {"Kp": 10, "Ki": 20, "ramp_error": "0 in"},
}


class RigMemo(dict[RigCase, "RigVerdict | None"]):
    """Rig verdicts shared by the request threads, each design simulated once (single flight).

    The grader asks ``case in memo`` before simulating and stores the verdict after; the first
    thread to ask about a missing case simulates it, later ones wait for its verdict instead of
    simulating the same design again.
    """

    def __init__(self) -> None:
        super().__init__()
        self._lock = threading.Lock()
        self._running: dict[RigCase, threading.Event] = {}

    def __contains__(self, case: object) -> bool:
        with self._lock:
            if dict.__contains__(self, case):
                return True
            running = self._running.get(case)  # type: ignore[call-overload]
            if running is None:
                self._running[case] = threading.Event()  # type: ignore[index]
                return False  # the caller simulates it and stores the verdict
        if not running.wait(RIG_WAIT_S):  # the simulating thread failed: let the next one try
            with self._lock:
                if self._running.get(case) is running:  # type: ignore[call-overload]
                    del self._running[case]  # type: ignore[arg-type]
            running.set()
        return dict.__contains__(self, case)

    def __setitem__(self, case: RigCase, verdict: RigVerdict | None) -> None:
        with self._lock:
            if len(self) >= RIG_MEMO_SIZE:
                self.clear()
            dict.__setitem__(self, case, verdict)
            done = self._running.pop(case, None)
        if done is not None:
            done.set()


@dataclass
class CheckService:
    """Checks submissions for the web server (thread-safe; one per worker process)."""

    opts: GradeOptions
    store: KeyStore
    _keys: dict[str, KeyContext] = field(default_factory=dict, repr=False)
    _rig: RigMemo = field(default_factory=RigMemo, repr=False)
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    def stations(self) -> list[str]:
        """The stations whose lab data are installed."""
        return self.store.stations()

    def warm(self) -> None:
        """Resolve every station's key and check :data:`WARM_ANSWERS` against it now (at start-up),
        rather than on the first students' requests."""
        answers = {k: v for k, v in WARM_ANSWERS.items() if k in self.opts.rubric.items}
        for station in self.stations():
            try:
                self._key(station)
                self.check_document({"submission_id": "warm-up", "station": station, "answers": answers})
            except GraderError:
                continue  # a broken station dataset: its submissions get the prelab-only note

    def _key(self, station: str) -> KeyContext:
        kc = self._keys.get(station)
        if kc is None:
            with self._lock:
                kc = self._keys.get(station) or self.store.for_station(station)
                self._keys[station] = kc
        return kc

    def _resolve(self, sub: Submission) -> KeyContext:
        if sub.data is not None:
            raise SubmissionError("the web check uses the station's lab data; check a submission that brings "
                                  "its group's own data with 'grader check'")
        return self._key(sub.station)

    def check(self, sub: Submission) -> SubmissionResult:
        """Statuses and key-safe feedback for ``sub``."""
        return self_check(sub, self._resolve, self.opts, rig=self._rig)

    def check_document(self, doc: Any) -> SubmissionResult:
        """Check a parsed JSON submission document (``submission_id`` and ``students`` optional)."""
        if not isinstance(doc, dict):
            raise SubmissionError(f"submission: must be a JSON object at the top level, got {type(doc).__name__}")
        if "data" in doc:
            raise SubmissionError("submission: field data: the web check uses the station's lab data; "
                                  "check your group's own data with 'grader check'")
        return self.check(from_mapping(Path("submission.json"), {**DOC_DEFAULTS, **doc}))

    def check_upload(self, name: str, content: bytes) -> SubmissionResult:
        """Check an uploaded JSON, YAML or XLSX file; it is written only inside a temporary folder."""
        suffix = Path(name).suffix.lower()
        with tempfile.TemporaryDirectory(prefix="grader-web-") as tmp:
            path = Path(tmp) / f"upload{suffix}"  # never the client's name: nothing escapes the folder
            path.write_bytes(content)
            try:
                sub = read_submission(path, limits=self.opts.limits)
            except SubmissionError as exc:  # name the student's file in the message, not ours
                raise SubmissionError(str(exc).replace(path.name, fallback_id(Path(name)) + suffix, 1)) from None
            return self.check(sub)


def result_document(result: SubmissionResult) -> dict[str, Any]:
    """The API's response: ``submission_id``, per item ``item``/``status``/``feedback``, ``notes``."""
    return {"submission_id": result.submission_id,
            "items": [{"item": i.item, "status": i.status, "feedback": i.feedback} for i in result.items],
            "notes": list(result.notes)}


def build_service(rubric_path: Path, stations: Path | None, keys: Path | None) -> CheckService:
    """The service for ``grader serve``: the rubric, and the stations' datasets and keys folders."""
    from grader.grading.rubric import load_rubric

    rubric = load_rubric(rubric_path)
    opts = GradeOptions(rubric=rubric, convention=rubric.feedback_convention, reveal=False)
    if stations is not None and keys is None and (stations.parent / "keys").is_dir():
        keys = stations.parent / "keys"
    return CheckService(opts, KeyStore(datasets_dir=stations, keys_dir=keys))

