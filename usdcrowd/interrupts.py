"""Ctrl-C and kill are answered at once: workers stopped, the frame in flight dropped, nothing orphaned.

The command line turns SIGTERM (``kill``, ``timeout``, a farm's scheduler)
into :class:`Terminated`, raised in the main thread like Ctrl-C's
KeyboardInterrupt, so the same clean-up runs for both. Worker processes
ignore SIGINT (a terminal sends it to the whole process group): the parent
alone decides, and stops them with :func:`stop_pool`.
"""

from __future__ import annotations

import contextlib
import signal

# How long a worker gets to exit after SIGTERM before it is killed.
WORKER_GRACE_S = 1.0


class Terminated(BaseException):
    """SIGTERM arrived: stop as for Ctrl-C (a BaseException, so no ``except Exception`` swallows it)."""


def _raise_terminated(signum, frame):
    raise Terminated(signum)


@contextlib.contextmanager
def terminate_as_exception():
    """Within: SIGTERM raises :class:`Terminated` in the main thread (the previous handler is restored)."""
    try:
        previous = signal.signal(signal.SIGTERM, _raise_terminated)
    except ValueError:                      # not the main thread: leave signals alone
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


@contextlib.contextmanager
def signals_held(*signums):
    """The signals wait while inside (delivered on leaving). Processes started inside are born with them
    blocked: the mask survives fork and exec.

    Blocking them in this thread is not enough: the kernel may hand a signal to another thread (a progress
    bar's, a writer's), and Python then runs its handler in the main thread at the next check, which a
    long write makes between two chunks (a child's start-up pickle cut short). So the Python handlers
    are also deferred: a signal that arrives inside is raised again on leaving.
    """
    deferred: list[int] = []
    handlers = {}
    try:
        for signum in signums:
            handlers[signum] = signal.signal(signum, lambda n, _frame: deferred.append(n))
    except ValueError:                      # not the main thread: its handlers are not ours to change
        pass
    try:
        old = signal.pthread_sigmask(signal.SIG_BLOCK, set(signums))
    except (AttributeError, ValueError, OSError):
        old = None
    try:
        yield
    finally:
        if old is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, old)
        for signum, handler in handlers.items():
            signal.signal(signum, handler)
        for signum in dict.fromkeys(deferred):
            signal.raise_signal(signum)


def children_deaf_to_ctrl_c():
    """Processes started within cannot be stopped by Ctrl-C or kill half-way through their start-up (a
    truncated start-up pickle, a traceback); here such a signal waits and is delivered on leaving. The
    workers unblock SIGTERM first thing (:func:`worker_ignores_interrupts`)."""
    return signals_held(signal.SIGINT, signal.SIGTERM)


def worker_ignores_interrupts() -> None:
    """Run first in each worker process: Ctrl-C reaches the parent, which stops the workers itself."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGTERM})   # blocked by the parent while it started us
    # tqdm's default lock is a multiprocessing semaphore: a worker stopped mid-task would leave it
    # registered, and the resource tracker would warn at the parent's exit. A worker's bars are its own.
    import threading

    from tqdm import tqdm

    tqdm.set_lock(threading.RLock())


def _descendants(pid: int) -> list[int]:
    """Process ids started by ``pid`` and by those, from /proc (Linux); [] where it cannot be read."""
    found, todo = [], [pid]
    while todo:
        parent = todo.pop()
        try:
            with open(f"/proc/{parent}/task/{parent}/children") as fh:
                children = [int(c) for c in fh.read().split()]
        except (OSError, ValueError):
            children = []
        found += children
        todo += children
    return found


def stop_processes(processes) -> None:
    """SIGTERM each live process and what it started (a dataset worker's part writers), then SIGKILL what
    is left after :data:`WORKER_GRACE_S`; reap them all."""
    import os

    processes = [p for p in processes if p is not None]
    grandchildren = [pid for p in processes if p.pid for pid in _descendants(p.pid)]
    for pid in grandchildren:
        with contextlib.suppress(OSError):
            os.kill(pid, signal.SIGTERM)
    for p in processes:
        with contextlib.suppress(Exception):
            if p.is_alive():
                p.terminate()
    for p in processes:
        with contextlib.suppress(Exception):
            p.join(WORKER_GRACE_S)
            if p.is_alive():
                p.kill()
                p.join(WORKER_GRACE_S)


def stop_pool(pool) -> None:
    """Stop a ProcessPoolExecutor now: queued tasks cancelled, running ones abandoned, workers ended."""
    with signals_held(signal.SIGINT, signal.SIGTERM):    # a second Ctrl-C must not leave workers running
        processes = list((getattr(pool, "_processes", None) or {}).values())
        pool.shutdown(wait=False, cancel_futures=True)
        stop_processes(processes)
        # The pool's manager thread sees its workers gone and releases the queues' semaphores (else the
        # resource tracker warns about them at exit); with no worker left this returns at once.
        pool.shutdown(wait=True)
