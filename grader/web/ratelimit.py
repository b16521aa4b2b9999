"""A per-client token bucket: ``per_minute`` requests a minute on average, bursts up to ``burst``.

Counts live in the worker process's memory (each uvicorn worker keeps its own), keyed by the
client address uvicorn reports (behind a reverse proxy: the forwarded address, when uvicorn
is told to trust the proxy). The table is bounded: the idlest clients are forgotten first.
"""

from __future__ import annotations

import threading
import time
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, field

MAX_CLIENTS = 10_000


@dataclass
class RateLimiter:
    """``allow(client)`` is False when the client has used its budget (``per_minute`` 0: no limit)."""

    per_minute: float
    burst: float
    clock: Callable[[], float] = time.monotonic
    _buckets: OrderedDict[str, tuple[float, float]] = field(default_factory=OrderedDict, repr=False)
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    def allow(self, client: str) -> bool:
        if self.per_minute <= 0:
            return True
        now = self.clock()
        with self._lock:
            tokens, last = self._buckets.pop(client, (self.burst, now))
            tokens = min(self.burst, tokens + (now - last) * self.per_minute / 60.0)
            ok = tokens >= 1.0
            self._buckets[client] = (tokens - 1.0 if ok else tokens, now)
            while len(self._buckets) > MAX_CLIENTS:
                self._buckets.popitem(last=False)
        return ok

    def retry_after(self) -> int:
        """Seconds until one more request is allowed for a client at zero tokens."""
        return max(1, round(60.0 / self.per_minute)) if self.per_minute > 0 else 0
