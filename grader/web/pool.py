"""Check processes for ``grader serve --workers N``: one server process takes every request and
hands the checks, in arrival order, to N worker processes.

Every worker builds its own :class:`~grader.web.service.CheckService` from the serve options and
warms it (keys, imports, the compiled engine) before the server answers ``/healthz``. One queue
in arrival order shares the load evenly over the workers whatever the clients' connections
(uvicorn's own worker processes each keep the connections they happen to accept, so one of
them can end up with most clients), and the checks' CPU never competes with the event loop
for the GIL, so the page and the previews stay responsive under load.
"""

from __future__ import annotations

import asyncio
import multiprocessing as mp
import os
import signal
import threading
import time
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any

from grader.web.service import CheckService, build_service, result_document

START_TIMEOUT_S = 300.0  # longest wait for every worker to build and warm its service
ORPHAN_POLL_S = 1.0  # how often a worker checks that its server is still there
_SERVICE: CheckService | None = None  # the worker process's own service


def service_from_options(cfg: dict[str, Any]) -> CheckService:
    """The service described by the serve options (``rubric``, ``stations``, ``keys``; paths or None)."""
    from grader.stations import repo_root
    from grader.web.commands import DEFAULT_RUBRIC

    return build_service(Path(cfg.get("rubric") or repo_root() / DEFAULT_RUBRIC),
                         Path(cfg["stations"]) if cfg.get("stations") else None,
                         Path(cfg["keys"]) if cfg.get("keys") else None)


def _start(cfg: dict[str, Any]) -> None:
    """Worker initializer: Ctrl-C is the server's to handle, and the worker ends with the server
    however that ends; build and warm this worker's service."""
    global _SERVICE
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    threading.Thread(target=_orphan_watch, args=(os.getppid(),), daemon=True).start()
    _SERVICE = service_from_options(cfg)
    _SERVICE.warm()


def _orphan_watch(server: int) -> None:
    """End this worker once its server process is gone (even killed: nothing else would tell it)."""
    while os.getppid() == server:
        time.sleep(ORPHAN_POLL_S)
    os._exit(0)


def _pid() -> int:
    time.sleep(0.05)  # long enough for the other workers to take the other start-up calls
    return os.getpid()


def _check(method: str, *args: Any) -> dict[str, Any]:
    """In a worker: ``CheckService.check_document(doc)`` or ``.check_upload(name, content)`` as the API's document."""
    assert _SERVICE is not None
    return result_document(getattr(_SERVICE, method)(*args))


class CheckPool:
    """N warmed worker processes fed in arrival order (see module docstring)."""

    def __init__(self, cfg: dict[str, Any], workers: int) -> None:
        if workers < 1:
            raise ValueError(f"workers must be at least 1, got {workers}")
        self.cfg, self.workers = dict(cfg), workers
        self._lock = asyncio.Lock()
        self._pool = self._new_pool()

    def _new_pool(self) -> ProcessPoolExecutor:
        """A pool whose every worker has started and warmed (spawned: no state forked from the event loop)."""
        pool = ProcessPoolExecutor(self.workers, mp_context=mp.get_context("spawn"), initializer=_start,
                                   initargs=(self.cfg,))
        seen: set[int] = set()
        deadline = time.monotonic() + START_TIMEOUT_S
        while len(seen) < self.workers and time.monotonic() < deadline:
            seen |= {f.result() for f in [pool.submit(_pid) for _ in range(self.workers)]}
        return pool

    async def check(self, method: str, *args: Any) -> dict[str, Any]:
        """The API's result document of ``method`` (``check_document`` or ``check_upload``) on ``args``.

        A worker that died (killed, out of memory) fails only the requests it held: the pool is
        replaced and the error reaches the app's generic 500.
        """
        pool = self._pool
        try:
            return await asyncio.wrap_future(pool.submit(_check, method, *args))
        except BrokenProcessPool:
            async with self._lock:
                if self._pool is pool:
                    self._pool = await asyncio.to_thread(self._new_pool)
            raise

    def close(self) -> None:
        """Stop the workers (at the server's shutdown): queued checks are cancelled, running ones end."""
        self._pool.shutdown(wait=True, cancel_futures=True)
