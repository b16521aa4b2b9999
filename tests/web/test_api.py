"""The JSON API (httpx2 or httpx through FastAPI's TestClient): same results as ``grader check``, key-safe, hostile-input safe."""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from grader.grading.context import KeyContext
from grader.grading.pipeline import resolve_key
from grader.grading.selfcheck import self_check
from grader.grading.submissions import read_submission
from grader.web.app import WebOptions, create_app
from grader.web.ratelimit import RateLimiter
from grader.web.service import CheckService

from .conftest import FIXTURES, reference_texts

CHECKED = ["correct.json", "correct.yaml", "unit_kq_ft3.json", "mistake_weight_as_mass.json", "ecf_kq.json",
           "tf_wrong.json", "bad_design_goal.json", "mistake_open_loop_poles.json", "wrong_dimension.json",
           "mistake_kpot_convention.json", "hostile_import.json", "hostile_types.json", "prelab_only.json"]
NUMBER = re.compile(r"\d+\.?\d*(?:e[-+]?\d+)?")


def _leaks(text: str, sent: str, kc: KeyContext, key_numbers: Callable[[KeyContext], set[str]]) -> set[str]:
    """Key values (3-6 significant figures) or reference expressions in ``text`` that were not in ``sent``."""
    numbers = set(NUMBER.findall(text)) - set(NUMBER.findall(sent))
    squeezed = text.replace(" ", "")
    return {t for t in key_numbers(kc) if t in numbers} | {r for r in reference_texts() if r in squeezed}


def test_healthz(client: TestClient) -> None:
    assert client.get("/healthz").status_code == 200


@pytest.mark.parametrize("name", CHECKED)
def test_check_matches_grader_check_and_reveals_nothing(name: str, client: TestClient, service: CheckService,
                                                        kc: KeyContext, key_numbers: Callable[[KeyContext], set[str]]) -> None:
    """Through the API exactly what ``grader check`` gives (its own path: file reader + KeyStore), and no key value."""
    path = FIXTURES / name
    sub = read_submission(path)
    expected = self_check(sub, lambda s: resolve_key(s, service.store), service.opts)
    if path.suffix == ".json":
        r = client.post("/api/check", content=path.read_bytes(), headers={"Content-Type": "application/json"})
    else:
        r = client.post("/api/check-file", files={"file": (name, path.read_bytes())})
    assert r.status_code == 200, r.text
    body = r.json()
    assert set(body) == {"submission_id", "items", "notes"} and body["submission_id"] == sub.submission_id
    assert [(i["item"], i["status"], i["feedback"]) for i in body["items"]] == \
        [(i.item, i.status, i.feedback) for i in expected.items]
    assert body["notes"] == list(expected.notes)
    assert not _leaks(r.text, path.read_text(errors="replace"), kc, key_numbers)


def test_xlsx_upload_matches_json(client: TestClient) -> None:
    x = client.post("/api/check-file", files={"file": ("lab4.xlsx", (FIXTURES / "correct.xlsx").read_bytes())}).json()
    j = client.post("/api/check", content=(FIXTURES / "correct.json").read_bytes()).json()
    assert [(i["item"], i["status"]) for i in x["items"]] == [(i["item"], i["status"]) for i in j["items"]]
    assert {i["status"] for i in x["items"]} == {"correct"}


def test_id_and_students_are_optional_and_implicit_products_grade(client: TestClient) -> None:
    typed = "s^3 + (B/M + 4beta Kce/Vt)s^2 + 4beta(A^2 + B Kce)/(M Vt) s + 4beta A Kp Kamp Kpot Kq/(M Vt) = 0"
    body = client.post("/api/check", json={"answers": {"char_poly": typed}}).json()
    statuses = {i["item"]: i["status"] for i in body["items"]}
    assert body["submission_id"] == "self-check"
    assert statuses["char_poly"] == "correct" and statuses["Kq"] == "missing"


BAD = [  # (body, status, words the one-line message must contain)
    (b"{not json", 400, "not valid JSON"),
    (b"[1, 2]", 422, "JSON object"),
    (b'{"answers": {}, "hack": 1}', 422, "hack"),
    (b'{"submission_id": "../../etc/passwd", "answers": {}}', 422, "submission_id"),
    (b'{"station": "default", "data": "../x", "answers": {}}', 422, "grader check"),
    (b'{"answers": ' * 5000, 400, "JSON"),
    (b'{"answers": {"Kq": 1' + b"0" * 5000 + b"}}", 400, "JSON"),
    (b"\xff\xfe", 400, "JSON"),
]


@pytest.mark.parametrize(("body", "status", "words"), BAD)
def test_bad_bodies_get_one_line_4xx(client: TestClient, body: bytes, status: int, words: str) -> None:
    r = client.post("/api/check", content=body, headers={"Content-Type": "application/json"})
    assert r.status_code == status, r.text
    message = r.json()["error"]
    assert words in message and "\n" not in message and "Traceback" not in message


def test_over_one_megabyte_is_413_by_length_and_while_streaming(client: TestClient) -> None:
    big = b'{"answers": {"Kq": "' + b"1" * 1_000_100 + b'"}}'
    assert client.post("/api/check", content=big).status_code == 413

    def chunks() -> Iterator[bytes]:  # no Content-Length: counted as it arrives
        for _ in range(20):
            yield b" " * 100_000
    assert client.post("/api/check", content=chunks()).status_code == 413
    big_json = {"file": ("big.json", b" " * 1_000_001 + b"{}")}
    assert client.post("/api/check-file", files=big_json).status_code == 413


def test_an_upload_over_its_limit_is_told_the_file_limit(service: CheckService, client: TestClient) -> None:
    """By Content-Length, the upload's own limit (not the limit plus the multipart overhead the server allows)."""
    cap = service.opts.limits.max_xlsx_bytes
    r = client.post("/api/check-file", content=b"x", headers={"Content-Length": str(cap + 1_000_000),
                                                              "Content-Type": "multipart/form-data; boundary=b"})
    assert r.status_code == 413 and r.json()["error"] == f"request body over the limit of {cap / 1e6:g} MB"


@pytest.mark.parametrize(("method", "path", "status", "words"), [
    ("GET", "/nope", 404, "not found: /nope"),
    ("GET", "/static/nope.js", 404, "not found: /static/nope.js"),
    ("GET", "/api/check", 405, "GET is not allowed on /api/check"),
])
def test_routing_errors_are_one_line_json_errors(client: TestClient, method: str, path: str, status: int,
                                                 words: str) -> None:
    """The ``{"error": ...}`` shape of every other error (docs/reference/web-api.md), not FastAPI's ``detail``."""
    r = client.request(method, path)
    assert r.status_code == status and r.json() == {"error": words}
    if status == 405:
        assert r.headers["Allow"] == "POST"


def test_an_answer_given_twice_is_refused(client: TestClient) -> None:
    body = b'{"answers": {"Kq": "1 in^3/s/mA", "Kq": "0.0385 in^3/s/mA"}}'
    r = client.post("/api/check", content=body, headers={"Content-Type": "application/json"})
    assert r.status_code == 422 and "'Kq' appears twice" in r.json()["error"]


def test_head_of_the_page(client: TestClient) -> None:
    r = client.head("/")
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/html") and not r.content


def test_upload_type_and_broken_files(client: TestClient) -> None:
    r = client.post("/api/check-file", files={"file": ("run.exe", b"MZ")})
    assert r.status_code == 415 and "unknown submission type" in r.json()["error"]
    r = client.post("/api/check-file", files={"file": ("lab.xlsx", b"PK\x03\x04 not a workbook")})
    assert r.status_code == 422 and "\n" not in r.json()["error"]
    r = client.post("/api/check-file", files={"file": ("group 7.yaml", b"a: &x [1]\nb: *x\n")})
    assert r.status_code == 422 and r.json()["error"].startswith("group_7.yaml: YAML aliases")
    doc = (FIXTURES / "correct.json").read_bytes()
    r = client.post("/api/check-file", files=[("file", ("a.json", doc)), ("file", ("b.json", doc))])
    assert r.status_code == 422 and r.json()["error"] == "file: upload one submission file at a time"
    for r in (client.post("/api/check-file"), client.post("/api/check-file", files={"file": ("", b"{}")})):
        assert r.status_code == 422 and r.json()["error"].startswith("file: no submission file in the upload")


def test_uploads_stay_in_a_temporary_folder(client: TestClient, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    monkeypatch.setattr("tempfile.tempdir", str(tmp))
    monkeypatch.chdir(tmp_path)
    doc = (FIXTURES / "correct.json").read_bytes()
    for name in ("../../escape.json", "/etc/escape.json", "..\\escape.json"):
        assert client.post("/api/check-file", files={"file": (name, doc)}).status_code == 200
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["tmp"]  # nothing left, nothing outside


def test_internal_error_is_generic_500(service: CheckService, monkeypatch: pytest.MonkeyPatch) -> None:
    client = TestClient(create_app(service), raise_server_exceptions=False)

    def boom(doc: object) -> None:
        raise RuntimeError("secret detail /home/x/key.json")
    monkeypatch.setattr(service, "check_document", boom)
    r = client.post("/api/check", json={"answers": {}})
    assert r.status_code == 500 and "secret" not in r.text and "Traceback" not in r.text
    assert "internal error" in r.json()["error"]


def test_rate_limit_gives_429(service: CheckService) -> None:
    client = TestClient(create_app(service, WebOptions(checks_per_minute=60, burst=3)))
    codes = [client.post("/api/check", json={"answers": {}}).status_code for _ in range(5)]
    assert codes == [200, 200, 200, 429, 429]
    r = client.post("/api/check", json={"answers": {}})
    assert "too many requests" in r.json()["error"] and r.headers["Retry-After"] == "1"
    assert "wait 1 s" in r.json()["error"]


def test_rate_limiter_refills_per_client() -> None:
    now = [0.0]
    rl = RateLimiter(per_minute=6, burst=2, clock=lambda: now[0])
    assert [rl.allow("a") for _ in range(3)] == [True, True, False]
    assert rl.allow("b")  # another client has its own budget
    now[0] = 10.0  # 6 a minute: one more after 10 s
    assert [rl.allow("a"), rl.allow("a")] == [True, False]
    assert all(RateLimiter(per_minute=0, burst=0).allow("x") for _ in range(100))


PREVIEWS = [  # (item, typed, read as)
    ("closed_loop_tf", "4 beta Kq A", "4 * beta * Kq * A"),
    ("char_poly", "2(s+1)", "2 * (s + 1)"),
    ("open_loop_tf", "Kp Kamp Kpot", "Kp * Kamp * Kpot"),
    ("char_poly", "4beta s^2", "4 * beta * s ^ 2"),
    ("Kq", "0.0385 in^3/s/mA", "0.0385 in³/mA/s"),
]


@pytest.mark.parametrize(("item", "typed", "read_as"), PREVIEWS)
def test_preview_shows_how_the_input_is_read(client: TestClient, item: str, typed: str, read_as: str) -> None:
    body = client.post("/api/preview", json={"item": item, "text": typed}).json()
    assert body["read_as"] == read_as and body["latex"]


def test_preview_kpot_is_one_symbol_and_injection_is_refused(client: TestClient) -> None:
    assert "K_{\\mathrm{pot}}" in client.post("/api/preview", json={"item": "char_poly", "text": "Kpot s"}).json()["latex"]
    body = client.post("/api/preview", json={"item": "char_poly", "text": "__import__('os').system('id')"}).json()
    assert set(body) == {"error"} and "not allowed" in body["error"]
    assert client.post("/api/preview", json={"item": "Kq", "text": "not reachable"}).json() == {}
    assert client.post("/api/preview", json={"text": "s"}).status_code == 422


def test_page_has_every_hook_and_no_key(client: TestClient, service: CheckService, kc: KeyContext,
                                        key_numbers: Callable[[KeyContext], set[str]]) -> None:
    page = client.get("/").text
    for item in service.opts.rubric.items:
        assert f'data-testid=\'answer-{item}\'' in page and f"data-testid='result-{item}'" in page
        assert f"<label for='a-{item}'>" in page and f"id='a-{item}'" in page
    assert 'data-testid="upload"' in page and 'data-testid="check"' in page
    order = [page.index(title) for title in ("Prelab", "Characterisation", "Identification", "Predictions", "Designs")]
    assert order == sorted(order)
    assert "unit: in^3/s/mA" in page and "<option value='default'>" in page
    assert not _leaks(page, "", kc, key_numbers)
    for asset in ("/static/app.js", "/static/app.css"):
        r = client.get(asset)
        assert r.status_code == 200 and not _leaks(r.text, "", kc, key_numbers)
    for asset in ("/static/katex/katex.min.js", "/static/katex/katex.min.css", "/static/katex/fonts/KaTeX_Main-Regular.woff2"):
        assert client.get(asset).status_code == 200  # bundled: the page needs no internet
    assert json.loads(client.get("/api/stations").text) == {"stations": ["default"]}


def test_rig_memo_simulates_each_design_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """Threads asking for the same missing design: one simulates, the others wait for its verdict."""
    import threading

    from grader.web import service as svc

    memo, case, answers = svc.RigMemo(), object(), []
    assert (case in memo) is False  # this thread now simulates it

    def ask() -> None:
        answers.append(case in memo)
    waiters = [threading.Thread(target=ask) for _ in range(3)]
    for t in waiters:
        t.start()
    memo[case] = "verdict"  # type: ignore[index]
    for t in waiters:
        t.join(5)
    assert answers == [True, True, True] and memo[case] == "verdict"  # type: ignore[index]
    monkeypatch.setattr(svc, "RIG_WAIT_S", 0.01)
    other = object()
    assert (other in memo) is False and (other in memo) is False  # a failed simulation does not block for ever
    assert (other in memo) is False


def test_serve_builds_each_worker_from_its_options(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """``grader serve``'s worker factory: rubric, stations folder (keys beside it) and rate limit from the env."""
    from grader.web.commands import ENV, app_from_env

    from .conftest import REFERENCE, RUBRIC

    monkeypatch.setenv(ENV, json.dumps({"rubric": str(RUBRIC), "stations": str(REFERENCE / "datasets"),
                                        "rate_limit": 60, "burst": 1}))
    client = TestClient(app_from_env())
    assert client.get("/api/stations").json() == {"stations": ["default"]}
    assert [client.post("/api/check", json={"answers": {}}).status_code for _ in range(2)] == [200, 429]
    monkeypatch.setenv(ENV, json.dumps({"stations": str(tmp_path)}))  # no lab data: prelab only, said so
    body = TestClient(app_from_env()).post("/api/check", json={"answers": {}}).json()
    assert any("no lab data" in n for n in body["notes"]) and len(body["items"]) == 3


def test_serve_with_workers_checks_in_warmed_processes(monkeypatch: pytest.MonkeyPatch, client: TestClient) -> None:
    """``grader serve --workers 1``: checks run in a spawned, warmed process and give what the threads give;
    an unreadable submission raised there is still a one-line 422; a worker that dies fails only the check it held (a generic 500) and the next check gets a new worker."""
    import os
    import signal

    from grader.web.commands import ENV, app_from_env

    from .conftest import REFERENCE, RUBRIC

    monkeypatch.setenv(ENV, json.dumps({"rubric": str(RUBRIC), "stations": str(REFERENCE / "datasets"),
                                        "rate_limit": 0, "workers": 1}))
    body = (FIXTURES / "correct.json").read_bytes()
    app = app_from_env()
    with TestClient(app, raise_server_exceptions=False) as pooled:  # the context runs start-up and shutdown
        got = pooled.post("/api/check", content=body, headers={"Content-Type": "application/json"})
        bad = pooled.post("/api/check", json={"station": "default", "answers": "not a mapping"})
        pool = app.state.pool
        for pid in list(pool._pool._processes):  # the worker dies (killed, out of memory...)
            os.kill(pid, signal.SIGKILL)
        lost = pooled.post("/api/check", json={"answers": {}})
        again = pooled.post("/api/check", json={"answers": {}})
    expected = client.post("/api/check", content=body, headers={"Content-Type": "application/json"})
    assert got.status_code == 200 and got.json() == expected.json()
    assert bad.status_code == 422 and "answers" in bad.json()["error"]
    assert lost.status_code == 500 and "Traceback" not in lost.text and again.status_code == 200


def test_serve_refuses_zero_workers(capsys: pytest.CaptureFixture[str]) -> None:
    from grader.cli import main

    assert main(["serve", "--workers", "0"]) == 2
    assert "--workers must be at least 1" in capsys.readouterr().err
