"""Load benchmark of ``grader serve``: 1,000 mixed checks from 50 concurrent clients on loopback.

    python benchmarks/web_benchmark.py [--n 1000] [--clients 50] [--workers 2] [--unique-designs]

Starts ``grader serve`` as a subprocess on a free loopback port (rate limit off: every client
here shares one address), waits for ``/healthz``, then sends ``--n`` POST /api/check requests
from ``--clients`` concurrent clients. The submissions are those of
``benchmarks/grading_benchmark.py`` (grading fixtures with jittered numbers; full checks with PD
and PI designs in 80 % of them, gains picked from the round numbers students choose, or every
one distinct with ``--unique-designs``). Bounded in count and in time (``--max-seconds``).
Reports throughput and p50/p95/max latency per pass (``--passes 2`` sends the same checks again
to the same server: the first pass meets a cold server, whose first check of each design runs
its rig simulation; the second shows the steady state, where verdicts are reused).
Goal: p95 <= 1 s on 2 cores.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx

sys.path.insert(0, str(Path(__file__).resolve().parent))
from grading_benchmark import ROOT, make_submissions  # noqa: E402


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _start(port: int, workers: int, log: Path) -> subprocess.Popen[bytes]:
    cmd = [sys.executable, "-m", "grader.cli", "serve", "--port", str(port), "--workers", str(workers),
           "--rate-limit", "0", "--no-access-log"]
    with log.open("wb") as out:  # the server's log: counts per check only
        proc = subprocess.Popen(cmd, cwd=ROOT, stdout=out, stderr=subprocess.STDOUT, start_new_session=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        try:
            if httpx.get(f"http://127.0.0.1:{port}/healthz", timeout=1).status_code == 200:
                return proc
        except httpx.HTTPError:
            time.sleep(0.3)
    _stop(proc)
    raise SystemExit("grader serve did not answer /healthz within 120 s")


def _stop(proc: subprocess.Popen[bytes]) -> None:
    """Stop the server and its worker processes (its own process group)."""
    os.killpg(proc.pid, signal.SIGTERM)
    try:
        proc.wait(15)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(5)


async def _load(url: str, bodies: list[bytes], clients: int, max_seconds: float) -> list[tuple[float, int]]:
    """(latency s, status code) per request, in completion order. aiohttp's client: it spends a
    fraction of httpx's CPU per request, which matters when the clients share the server's cores."""
    import aiohttp

    queue: asyncio.Queue[bytes] = asyncio.Queue()
    for b in bodies:
        queue.put_nowait(b)
    out: list[tuple[float, int]] = []
    connector = aiohttp.TCPConnector(limit=clients)
    async with aiohttp.ClientSession(connector=connector, timeout=aiohttp.ClientTimeout(total=300)) as client:
        async def worker() -> None:
            while not queue.empty():
                body = queue.get_nowait()
                t0 = time.perf_counter()
                try:
                    async with client.post(url, data=body, headers={"Content-Type": "application/json"}) as r:
                        await r.read()
                        code = r.status
                except (aiohttp.ClientError, asyncio.TimeoutError):
                    code = 0  # no reply (timeout, connection lost)
                out.append((time.perf_counter() - t0, code))
        await asyncio.wait_for(asyncio.gather(*(worker() for _ in range(clients))), max_seconds)
    return out


def _summary(label: str, lat: list[float]) -> str:
    q = statistics.quantiles(lat, n=100)
    return f"{label}: p50 {q[49] * 1e3:.0f} ms, p95 {q[94] * 1e3:.0f} ms, max {max(lat) * 1e3:.0f} ms"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1000)
    ap.add_argument("--clients", type=int, default=50)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--unique-designs", action="store_true")
    ap.add_argument("--max-seconds", type=float, default=600, help="time bound per pass")
    ap.add_argument("--passes", type=int, default=1, help="send the same checks this many times (default: 1)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        make_submissions(Path(tmp), args.n, unique_designs=args.unique_designs)
        bodies = [p.read_bytes() for p in sorted(Path(tmp).glob("*.json"))]
    designs = sum("pd_design" in json.loads(b)["answers"] for b in bodies)
    port = _free_port()
    log = Path(tempfile.gettempdir()) / f"grader-web-benchmark-{port}.log"
    proc = _start(port, args.workers, log)
    codes: set[int] = set()
    try:
        for k in range(args.passes):
            t0 = time.perf_counter()
            done = asyncio.run(_load(f"http://127.0.0.1:{port}/api/check", bodies, args.clients, args.max_seconds))
            wall = time.perf_counter() - t0
            codes |= {c for _, c in done}
            print(f"pass {k + 1}: {len(done)} checks ({designs} with PD/PI designs) from {args.clients} clients, "
                  f"{args.workers} workers, {os.cpu_count()} CPUs: {wall:.1f} s, {len(done) / wall:.1f} checks/s, "
                  f"status codes {sorted({c for _, c in done})} (0: no reply)")
            print("  " + _summary("latency", [t for t, _ in done]))
    finally:
        _stop(proc)
    print(f"server log (counts only): {log}")
    return 0 if codes == {200} else 1


if __name__ == "__main__":
    sys.exit(main())
