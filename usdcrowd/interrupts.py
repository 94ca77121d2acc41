"""Ctrl-C and kill are answered at once: workers stopped, the frame in flight dropped, nothing orphaned.

The command line turns SIGTERM (``kill``, ``timeout``, a farm's scheduler)
into :class:`Terminated`, raised in the main thread like Ctrl-C's
KeyboardInterrupt, so the same clean-up runs for both
(:func:`stops_as_exceptions`). Worker processes
ignore SIGINT (a terminal sends it to the whole process group): the parent
alone decides, and stops them with :func:`stop_pool`.
"""

from __future__ import annotations

import contextlib
import signal
import sys

# How long a worker gets to exit after SIGTERM before it is killed.
WORKER_GRACE_S = 1.0


class Terminated(BaseException):
    """SIGTERM arrived: stop as for Ctrl-C (a BaseException, so no ``except Exception`` swallows it)."""


# A stop that lands inside an import can leave a compiled module half set up (USD then warns that its
# converters are registered twice, or swallows the stop), and one raised in a finaliser is printed and
# dropped: either is delivered again this much later (until no import is under way).
STOP_RETRY_S = 0.05
# A stop that a library swallows (trimesh catches any BaseException around its sparse normals, logs it and
# goes on with a loop fifty times slower) is delivered again this often until the command ends; not while
# a stop's own clean-up runs (an exception being handled): that finishes first.
STOP_WATCH_S = 0.25


def _stop_for(signum: int) -> BaseException:
    return KeyboardInterrupt() if signum == signal.SIGINT else Terminated(signum)


def _importing(frame) -> bool:
    """Whether ``frame`` runs inside an import (a module's own code, or what it calls)."""
    while frame is not None:
        if frame.f_code.co_filename.startswith("<frozen importlib"):
            return True
        frame = frame.f_back
    return False


@contextlib.contextmanager
def stops_as_exceptions():
    """Within: SIGTERM raises :class:`Terminated` and Ctrl-C KeyboardInterrupt in the main thread, and
    whatever escapes after either arrived leaves as that stop, as does a normal end after one was
    swallowed (the previous handlers are restored).

    A stop that lands during an import waits for it to end; one raised in a finaliser is delivered
    again, and so is one a library swallows, every :data:`STOP_WATCH_S` until it leaves (a second Ctrl-C
    while a stop's clean-up runs waits for it). One can still land inside a library that turns it into
    something else: numba's dispatcher raises a SystemError; trimesh's optional imports keep any
    BaseException in a placeholder that fails later. Those are the stop all the same, and leave as it
    (chained to what they became).
    """
    import os
    import threading

    asked: list[int] = []
    retries: list[threading.Timer] = []
    live = True

    def again(signum):
        if live:
            os.kill(os.getpid(), signum)

    def later(signum, delay=STOP_RETRY_S):
        retry = threading.Timer(delay, again, (signum,))
        retry.daemon = True
        retries.append(retry)
        retry.start()

    def stop(signum, frame):
        stopping_already = bool(asked)
        asked.append(signum)
        if _importing(frame):
            later(signum)
            return
        later(signum, STOP_WATCH_S)             # should a library swallow this one
        if stopping_already and sys.exc_info()[1] is not None:
            return                              # the stop is on its way out, its clean-up running
        raise _stop_for(signum)

    def unraisable(report):
        # Raised inside a finaliser (__del__, a weakref's callback), the stop cannot leave it: Python
        # would print it as "Exception ignored" and go on. It is delivered again instead.
        if asked and isinstance(report.exc_value, (KeyboardInterrupt, Terminated)):
            later(asked[0])
        else:
            earlier_hook(report)

    earlier_hook, sys.unraisablehook = sys.unraisablehook, unraisable

    previous = {}
    try:
        previous[signal.SIGTERM] = signal.signal(signal.SIGTERM, stop)
        # Ctrl-C is taken only where Python's own handler has it: a shell that started us with it
        # ignored (a background job) meant it to stay ignored.
        if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            previous[signal.SIGINT] = signal.signal(signal.SIGINT, stop)
    except ValueError:                      # not the main thread: leave signals alone
        pass
    try:
        yield
    except BaseException as exc:
        if asked and not isinstance(exc, (KeyboardInterrupt, Terminated)):
            raise _stop_for(asked[0]) from exc
        raise
    else:
        if asked:       # swallowed on the way, or still waiting for an import: the exit says it
            raise _stop_for(asked[0])
    finally:
        live = False
        sys.unraisablehook = earlier_hook
        for retry in retries:
            retry.cancel()
        for signum, handler in previous.items():
            signal.signal(signum, handler)


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
