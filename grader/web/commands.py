"""CLI verb ``grader serve``: the students' self-check page and JSON API (FastAPI on uvicorn).

Heavy imports (fastapi, uvicorn, the grading stack) happen inside the handler. With
``--workers`` > 1 uvicorn starts that many processes, each building the app from the
``GRADER_SERVE`` environment variable through :func:`app_from_env`.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path
from typing import Any

ENV = "GRADER_SERVE"  # JSON of the serve options, read by each worker process
DEFAULT_RUBRIC = "rubrics/hydraulic_positioner.yaml"


def app_from_env() -> Any:
    """The app for one worker, configured from ``$GRADER_SERVE`` (uvicorn factory)."""
    from grader.stations import repo_root
    from grader.web.app import WebOptions, create_app
    from grader.web.service import build_service

    cfg = json.loads(os.environ.get(ENV, "{}"))
    _log_setup()
    service = build_service(Path(cfg.get("rubric") or repo_root() / DEFAULT_RUBRIC),
                            Path(cfg["stations"]) if cfg.get("stations") else None,
                            Path(cfg["keys"]) if cfg.get("keys") else None)
    service.warm()
    return create_app(service, WebOptions(checks_per_minute=cfg.get("rate_limit", 60.0), burst=cfg.get("burst", 30.0)))


def _log_setup() -> None:
    """grader.web's count lines at INFO on stderr, in every worker process (never an answer)."""
    import logging

    logging.basicConfig(level=logging.WARNING, format="%(asctime)s %(name)s %(levelname)s %(message)s")
    logging.getLogger("grader.web").setLevel(logging.INFO)


def _serve(args: argparse.Namespace) -> int:
    import uvicorn

    os.environ[ENV] = json.dumps({"rubric": args.rubric, "stations": args.stations, "keys": args.keys,
                                  "rate_limit": args.rate_limit, "burst": args.burst})
    print(f"grader serve: http://{args.host}:{args.port}/  (Ctrl-C to stop)")
    uvicorn.run("grader.web.commands:app_from_env", factory=True, host=args.host, port=args.port,
                workers=args.workers, proxy_headers=True, forwarded_allow_ips=args.forwarded_allow_ips,
                access_log=not args.no_access_log, log_level="info",
                timeout_worker_healthcheck=60)  # a worker busy with rig simulations is not hung
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("serve", help="serve the students' self-check page and JSON API (never shows the key)")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default: 127.0.0.1)")
    p.add_argument("--port", type=int, default=8000, help="port (default: 8000)")
    p.add_argument("--rubric", help=f"rubric YAML (default: {DEFAULT_RUBRIC})")
    p.add_argument("--stations", help="folder of station datasets, one sub-folder each (default: "
                   "reference_solutions/datasets); checked-in keys are read from --keys or its sibling keys/")
    p.add_argument("--keys", help="folder of checked-in keys <station>.json (default: next to --stations)")
    p.add_argument("--workers", type=int, default=1, help="worker processes (default: 1; about one per core)")
    p.add_argument("--rate-limit", type=float, default=60.0,
                   help="checks a minute per client address, per worker (default: 60; 0: no limit)")
    p.add_argument("--burst", type=float, default=30.0, help="checks a client may send at once (default: 30)")
    p.add_argument("--forwarded-allow-ips", default="127.0.0.1",
                   help="proxies whose X-Forwarded-For is trusted for the client address (default: 127.0.0.1)")
    p.add_argument("--no-access-log", action="store_true", help="no per-request access log lines")
    p.set_defaults(handler=_serve)
