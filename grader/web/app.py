"""The self-check web app (FastAPI): the page ``/``, ``/healthz`` and the JSON API (docs/reference/web-api.md).

Untrusted input throughout: bodies are capped before they are read (413), every client has a
rate limit (429), bad input gets a one-line 4xx message, and anything unexpected a generic 500
with no traceback. Uploads are written only inside a temporary folder. Logs hold counts only,
never an answer.
"""

from __future__ import annotations

import json
import logging
import time
from collections import Counter
from collections.abc import AsyncIterator, Callable
from contextlib import asynccontextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import anyio
from fastapi import FastAPI, Request, UploadFile
from fastapi.exceptions import RequestValidationError
from fastapi.responses import HTMLResponse, JSONResponse
from fastapi.staticfiles import StaticFiles
from starlette.exceptions import HTTPException
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from grader.errors import GraderError
from grader.untrusted import unique_object
from grader.web.page import render_page
from grader.web.preview import preview
from grader.web.ratelimit import RateLimiter
from grader.web.service import CheckService, result_document

if TYPE_CHECKING:
    from grader.web.pool import CheckPool

STATIC = Path(__file__).parent / "static"
LOG = logging.getLogger("grader.web")
MAX_BODY = 1_000_000  # bytes: JSON bodies and JSON/YAML uploads
MULTIPART_OVERHEAD = 64_000  # bytes allowed on top of an XLSX upload's own limit


@dataclass(frozen=True)
class WebOptions:
    """Rate limits: checks per minute per client (0: none) and the burst allowed (previews get 10x);
    ``threads``: checks run at once per worker (CPU-bound: more only add contention)."""

    checks_per_minute: float = 60.0
    burst: float = 30.0
    threads: int = 4


class BodyTooLarge(Exception):
    """A request body over its limit."""


class BadJSON(Exception):
    """A request body that is not valid JSON (a 400)."""


async def _json_body(request: Request) -> Any:
    try:
        return json.loads(await request.body(), object_pairs_hook=unique_object)
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise BadJSON(f"body is not valid JSON: {getattr(exc, 'msg', exc)}") from None
    except (RecursionError, ValueError):
        raise BadJSON("body is not valid JSON (nested too deeply or a number too long)") from None


class BodyLimit:
    """ASGI middleware: refuse a body over ``limit(path)`` bytes, by Content-Length or while it streams;
    ``shown(path)`` is the limit the 413 names (an upload's own, without the multipart overhead)."""

    def __init__(self, app: ASGIApp, limit: Callable[[str], int], shown: Callable[[str], int]) -> None:
        self.app, self.limit, self.shown = app, limit, shown

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        cap = self.limit(scope["path"])
        length = dict(scope["headers"]).get(b"content-length", b"0")
        if not length.isdigit() or int(length) > cap:
            await _too_large(self.shown(scope["path"]))(scope, receive, send)
            return
        seen = 0

        async def capped() -> Message:
            nonlocal seen
            message = await receive()
            seen += len(message.get("body", b""))
            if seen > cap:
                raise BodyTooLarge()
            return message

        await self.app(scope, capped, send)


def _too_large(cap: int) -> JSONResponse:
    return _error(413, f"request body over the limit of {cap / 1e6:g} MB")


def _error(status: int, message: str, **headers: str) -> JSONResponse:
    return JSONResponse({"error": " ".join(str(message).split())[:500]}, status_code=status, headers=headers)


def _client(request: Request) -> str:
    return request.client.host if request.client else "unknown"


def _count_log(result_items: list[dict[str, Any]], elapsed: float) -> None:
    """One log line per check: how many items had each status, and the time taken (never an answer)."""
    counts = Counter(i["status"] for i in result_items)
    LOG.info("check items=%d %s ms=%.0f", len(result_items),
             " ".join(f"{k}={v}" for k, v in sorted(counts.items())), elapsed * 1e3)


def _error_handlers(app: FastAPI, shown: Callable[[str], int]) -> None:
    """One-line JSON errors: 400 bad JSON, 404/405 (the routing's own), 413 too large, 422 unreadable submission,
    generic 500; ``shown(path)`` [bytes] is the body limit a 413 names."""

    @app.exception_handler(BodyTooLarge)
    async def _large(request: Request, exc: BodyTooLarge) -> JSONResponse:
        return _too_large(shown(request.url.path))

    @app.exception_handler(HTTPException)
    async def _http(request: Request, exc: HTTPException) -> JSONResponse:
        text = {404: f"not found: {request.url.path[:100]}",
                405: f"{request.method} is not allowed on {request.url.path[:100]}"}.get(exc.status_code, exc.detail)
        return _error(exc.status_code, text, **(exc.headers or {}))

    @app.exception_handler(BadJSON)
    async def _bad_json(request: Request, exc: BadJSON) -> JSONResponse:
        return _error(400, str(exc))

    @app.exception_handler(GraderError)
    async def _bad(request: Request, exc: GraderError) -> JSONResponse:
        return _error(422, str(exc))

    @app.exception_handler(RequestValidationError)
    async def _invalid(request: Request, exc: RequestValidationError) -> JSONResponse:
        first = exc.errors()[0] if exc.errors() else {}
        if tuple(first.get("loc", ())) == ("body", "file"):  # no upload, or a form field without a file name
            return _error(422, "file: no submission file in the upload (a .json, .yaml, .yml or .xlsx file in field "
                               "'file')")
        where = ".".join(str(x) for x in first.get("loc", ())) or "request"
        return _error(422, f"{where}: {first.get('msg', 'invalid request')}")

    @app.exception_handler(Exception)
    async def _internal(request: Request, exc: Exception) -> JSONResponse:
        LOG.error("internal error on %s: %s", request.url.path, type(exc).__name__)
        return _error(500, "internal error; the check could not be completed (please report it to your instructor)")


def create_app(service: CheckService, options: WebOptions = WebOptions(), pool: CheckPool | None = None) -> FastAPI:
    """The app: checks run in ``pool``'s worker processes, or in ``service`` on this process's threads."""

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        yield
        if pool is not None:
            pool.close()

    app = FastAPI(title="grader self-check", docs_url=None, redoc_url=None, openapi_url=None, lifespan=lifespan)
    app.state.pool = pool
    checks = RateLimiter(options.checks_per_minute, options.burst)
    previews = RateLimiter(options.checks_per_minute * 10, options.burst * 10)
    lanes = anyio.CapacityLimiter(options.threads)
    xlsx_cap = service.opts.limits.max_xlsx_bytes

    def shown(path: str) -> int:
        """The body limit [bytes] of ``path``: an upload's own file limit, or that of a JSON body."""
        return xlsx_cap if path == "/api/check-file" else MAX_BODY

    app.add_middleware(BodyLimit, shown=shown,
                       limit=lambda path: shown(path) + (MULTIPART_OVERHEAD if path == "/api/check-file" else 0))
    app.mount("/static", StaticFiles(directory=STATIC), name="static")
    page = render_page(service.opts.rubric, service.stations())

    _error_handlers(app, shown)

    def limited(limiter: RateLimiter, request: Request) -> JSONResponse | None:
        if limiter.allow(_client(request)):
            return None
        wait = limiter.retry_after()
        return _error(429, f"too many requests: at most {limiter.per_minute:g} a minute; wait {wait} s and try again",
                      **{"Retry-After": str(wait)})

    async def run_check(method: str, *args: Any) -> JSONResponse:
        start = time.perf_counter()
        if pool is not None:
            doc = await pool.check(method, *args)
        else:
            doc = result_document(await anyio.to_thread.run_sync(getattr(service, method), *args, limiter=lanes))
        _count_log(doc["items"], time.perf_counter() - start)
        return JSONResponse(doc)

    @app.api_route("/", methods=["GET", "HEAD"], response_class=HTMLResponse)
    async def index() -> HTMLResponse:
        return HTMLResponse(page, headers={"Content-Security-Policy": "default-src 'self'; object-src 'none'"})

    @app.get("/healthz")
    async def healthz() -> dict[str, str]:
        return {"status": "ok"}

    @app.get("/api/stations")
    async def stations() -> dict[str, list[str]]:
        return {"stations": service.stations()}

    @app.post("/api/check")
    async def check(request: Request) -> JSONResponse:
        if (refused := limited(checks, request)) is not None:
            return refused
        return await run_check("check_document", await _json_body(request))

    @app.post("/api/check-file")
    async def check_file(request: Request, file: UploadFile) -> JSONResponse:
        if (refused := limited(checks, request)) is not None:
            return refused
        if len((await request.form()).getlist("file")) > 1:  # FastAPI would check the last one alone
            return _error(422, "file: upload one submission file at a time")
        name = Path(file.filename or "upload").name
        suffix = Path(name).suffix.lower()
        if suffix not in (".json", ".yaml", ".yml", ".xlsx"):
            return _error(415, f"{name[:100]}: unknown submission type (use .json, .yaml, .yml or .xlsx)")
        content = await file.read()
        cap = service.opts.limits.max_xlsx_bytes if suffix == ".xlsx" else MAX_BODY
        if len(content) > cap:
            return _too_large(cap)
        return await run_check("check_upload", name, content)

    @app.post("/api/preview")
    async def preview_(request: Request) -> JSONResponse:
        if (refused := limited(previews, request)) is not None:
            return refused
        body = await _json_body(request)
        if not isinstance(body, dict) or not isinstance(body.get("item"), str) or not isinstance(body.get("text"), str):
            return _error(422, 'expected {"item": "<item>", "text": "<what was typed>"}')
        return JSONResponse(await anyio.to_thread.run_sync(preview, body["item"], body["text"], limiter=lanes))

    return app
