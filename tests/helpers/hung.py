"""A guard against a hang: the suite fails instead of blocking."""

from __future__ import annotations

import contextlib


@contextlib.contextmanager
def fails_if_hung(seconds: int, what: str):
    """Within, a hang raises TimeoutError after ``seconds`` instead of blocking the suite (SIGALRM)."""
    import signal

    def hung(*_):
        raise TimeoutError(f"{what} hung")

    old = signal.signal(signal.SIGALRM, hung)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
