"""A time limit for one call in a test: a hang fails the test instead of stalling the suite."""
from __future__ import annotations

import contextlib
import signal


class TimeLimitExceeded(Exception):
    """Raised inside the limited block when its time is up (never a HybridDynError)."""


@contextlib.contextmanager
def time_limit(seconds: float, what: str = "the call"):
    """Interrupt the block after ``seconds`` of wall time (SIGALRM: main thread, Unix)."""
    def on_alarm(signum, frame):
        raise TimeLimitExceeded(f"{what} ran past {seconds} s (a hang?)")

    old = signal.signal(signal.SIGALRM, on_alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
