"""CLI verb ``grader serve``: the students' self-check page and JSON API (FastAPI on uvicorn).

Heavy imports (fastapi, uvicorn, the grading stack) happen inside the handler. uvicorn builds
the app from the ``GRADER_SERVE`` environment variable through :func:`app_from_env`; the checks
run in ``--workers`` processes fed in arrival order (:mod:`grader.web.pool`).
"""

from __future__ import annotations

import argparse
import json
import os
from typing import Any

from grader.errors import GraderError

ENV = "GRADER_SERVE"  # JSON of the serve options, read by each worker process
DEFAULT_RUBRIC = "rubrics/hydraulic_positioner.yaml"


def app_from_env() -> Any:
    """The app configured from ``$GRADER_SERVE`` (uvicorn factory): with ``workers`` >= 1 the checks
    run in that many warmed worker processes, else on this process's threads."""
    from grader.web.app import WebOptions, create_app
    from grader.web.pool import CheckPool, service_from_options

    cfg = json.loads(os.environ.get(ENV, "{}"))
    _log_setup()
    service = service_from_options(cfg)
    workers = int(cfg.get("workers") or 0)
    if not workers:
        service.warm()
    options = WebOptions(checks_per_minute=cfg.get("rate_limit", 60.0), burst=cfg.get("burst", 30.0))
    return create_app(service, options, CheckPool(cfg, workers) if workers else None)


def _log_setup() -> None:
    """grader.web's count lines at INFO on stderr, in every worker process (never an answer)."""
    import logging

    logging.basicConfig(level=logging.WARNING, format="%(asctime)s %(name)s %(levelname)s %(message)s")
    logging.getLogger("grader.web").setLevel(logging.INFO)


def _serve(args: argparse.Namespace) -> int:
    import uvicorn

    if args.workers < 1:
        raise GraderError(f"--workers must be at least 1, got {args.workers}")
    os.environ[ENV] = json.dumps({"rubric": args.rubric, "stations": args.stations, "keys": args.keys,
                                  "rate_limit": args.rate_limit, "burst": args.burst, "workers": args.workers})
    print(f"grader serve: http://{args.host}:{args.port}/  (Ctrl-C to stop)")
    uvicorn.run("grader.web.commands:app_from_env", factory=True, host=args.host, port=args.port,
                proxy_headers=True, forwarded_allow_ips=args.forwarded_allow_ips,
                access_log=not args.no_access_log, log_level="info")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("serve", help="serve the students' self-check page and JSON API (never shows the key)")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default: 127.0.0.1)")
    p.add_argument("--port", type=int, default=8000, help="port (default: 8000)")
    p.add_argument("--rubric", help=f"rubric YAML (default: {DEFAULT_RUBRIC})")
    p.add_argument("--stations", help="folder of station datasets, one sub-folder each (default: "
                   "reference_solutions/datasets); checked-in keys are read from --keys or its sibling keys/")
    p.add_argument("--keys", help="folder of checked-in keys <station>.json (default: next to --stations)")
    p.add_argument("--workers", type=int, default=1,
                   help="processes that run the checks, fed in arrival order (default: 1; about one per core)")
    p.add_argument("--rate-limit", type=float, default=60.0,
                   help="checks a minute per client address (default: 60; 0: no limit)")
    p.add_argument("--burst", type=float, default=30.0, help="checks a client may send at once (default: 30)")
    p.add_argument("--forwarded-allow-ips", default="127.0.0.1",
                   help="proxies whose X-Forwarded-For is trusted for the client address (default: 127.0.0.1)")
    p.add_argument("--no-access-log", action="store_true", help="no per-request access log lines")
    p.set_defaults(handler=_serve)
