"""End to end in headless Chromium (Debian's /usr/bin/chromium via Playwright): type answers, press Check.

A correct transfer function (typed with implicit products), a wrong one, a unit slip and an
injection attempt; the statuses shown, the live KaTeX preview, keyboard use, phone width, and
that no key value reaches the page's HTML or any network response.
"""

from __future__ import annotations

import re
import shutil
import socket
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
import uvicorn

from grader.grading.context import KeyContext
from grader.web.app import WebOptions, create_app
from grader.web.service import CheckService

from .conftest import reference_texts

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
TYPED = {  # item -> (typed, expected status)
    "closed_loop_tf": ("4 beta A Kp Kamp Kpot Kq / (M Vt s^3 + (B Vt + 4beta Kce M)s^2 + 4beta(A^2 + B Kce)s"
                       " + 4 beta A Kp Kamp Kpot Kq)", "correct"),
    "open_loop_tf": ("Kp Kamp Kq / (s(M s^2 + B s + A))", "incorrect"),
    "Kq": ("0.03851 ft^3/s/mA", "unit_mismatch"),
    "char_poly": ("__import__('os').system('touch /tmp/grader-pwned')", "invalid"),
    "pd_design": ("Kp = 46, Kd = 0.2, overshoot = 13.8 %", "correct"),
}


@pytest.fixture(scope="module")
def base_url(service: CheckService) -> Iterator[str]:
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    server = uvicorn.Server(uvicorn.Config(create_app(service, WebOptions(checks_per_minute=600, burst=100)),
                                           log_level="warning"))
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    while not server.started:
        time.sleep(0.02)
    yield f"http://127.0.0.1:{sock.getsockname()[1]}"
    server.should_exit = True
    thread.join(5)


def test_page_in_chromium(base_url: str, kc: KeyContext, key_numbers: Callable[[KeyContext], set[str]]) -> None:
    from playwright.sync_api import expect, sync_playwright

    assert shutil.which(CHROMIUM), "Debian's chromium is needed: apt-get install chromium (.ci/run does)"
    bodies: list[str] = []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, headless=True)
        page = browser.new_page(viewport={"width": 1200, "height": 900})
        page.on("response", lambda r: bodies.append(r.text()) if "/static/katex/" not in r.url else None)
        page.goto(base_url + "/")
        for item, (typed, _) in TYPED.items():
            page.get_by_test_id(f"answer-{item}").fill(typed)
        expect(page.locator("#p-closed_loop_tf .katex")).to_be_visible()  # the live preview, rendered by KaTeX
        expect(page.locator("#p-char_poly")).to_contain_text("not allowed")
        page.get_by_test_id("check").focus()
        page.keyboard.press("Enter")  # usable from the keyboard
        for item, (_, status) in TYPED.items():
            shown = status.replace("_", " ")  # the status code in words
            expect(page.get_by_test_id(f"result-{item}")).to_contain_text(re.compile(rf"^{shown}\b"))
        assert "Kq" in page.get_by_test_id("result-Kq").inner_text()
        expect(page.get_by_test_id("answer-char_poly")).to_have_attribute("aria-invalid", "true")  # unreadable
        expect(page.get_by_test_id("answer-Kq")).not_to_have_attribute("aria-invalid", "true")
        html = page.content()
        page.set_viewport_size({"width": 360, "height": 800})  # phone width: nothing wider than the screen
        assert page.evaluate("document.documentElement.scrollWidth") <= 360
        browser.close()
    sent = " ".join(t for t, _ in TYPED.values())
    typed_numbers = set(re.findall(r"\d+\.?\d*", sent))
    for text in [html, *bodies]:
        numbers = set(re.findall(r"\d+\.?\d*(?:e[-+]?\d+)?", text)) - typed_numbers
        assert not {t for t in key_numbers(kc) if t in numbers}
        assert not any(r in text.replace(" ", "") for r in reference_texts())
    assert len(bodies) >= 4  # page, app.js, app.css, previews and the check were all inspected


def test_page_files_failures_focus_and_no_javascript(base_url: str, tmp_path: Path) -> None:
    """A chosen file is said to replace the typed answers and can be removed; a failed check leaves no result of the
    one before; a field reached by Tab is never hidden under the sticky Check bar; without JavaScript nothing is
    sent (the answers would otherwise land in the URL and the access log)."""
    from playwright.sync_api import expect, sync_playwright

    notes = tmp_path / "notes.txt"
    notes.write_text("not a submission", encoding="utf-8")
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, headless=True)
        page = browser.new_page(viewport={"width": 1280, "height": 900})
        page.goto(base_url + "/")
        page.get_by_test_id("answer-Kq").fill("0.0385 in^3/s/mA")
        page.get_by_test_id("check").click()
        expect(page.get_by_test_id("result-Kq")).not_to_be_empty()
        page.get_by_test_id("upload").set_input_files(str(notes))
        expect(page.get_by_test_id("file-note")).to_be_visible()
        page.get_by_test_id("check").click()
        expect(page.locator("#status")).to_contain_text("unknown submission type")
        expect(page.get_by_test_id("result-Kq")).to_be_empty()
        page.get_by_test_id("clear-file").click()
        expect(page.get_by_test_id("file-note")).to_be_hidden()
        page.get_by_test_id("check").click()
        expect(page.locator("#status")).to_contain_text("checked:")
        expect(page.get_by_test_id("result-Kq")).not_to_be_empty()

        page.evaluate("window.scrollTo(0, 0)")
        page.locator("#station").focus()
        hidden, seen = [], 0
        for _ in range(60):
            page.keyboard.press("Tab")
            where = page.evaluate("""() => { const a = document.activeElement, bar = document.querySelector('.actions');
                if (!a || a === document.body || bar.contains(a)) return null;
                return [a.id, a.getBoundingClientRect().bottom, bar.getBoundingClientRect().top]; }""")
            if where is None:
                continue
            seen += 1
            if where[1] > where[2]:
                hidden.append(where[0])
        assert seen >= 15 and not hidden, hidden

        quiet = browser.new_context(java_script_enabled=False).new_page()
        quiet.goto(base_url + "/")
        expect(quiet.locator(".nojs")).to_be_visible()
        expect(quiet.get_by_test_id("check")).to_be_disabled()
        quiet.get_by_test_id("answer-Kq").fill("0.0385 in^3/s/mA")
        quiet.get_by_test_id("answer-Kq").press("Enter")
        quiet.wait_for_timeout(300)
        assert "?" not in quiet.url and "0.0385" not in quiet.url
        browser.close()
