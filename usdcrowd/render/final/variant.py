"""Which Mitsuba variant renders here: chosen once, probed safely, reported.

Order of preference: ``cuda_ad_rgb`` (a GPU), ``llvm_ad_rgb`` (a CPU with a
working LLVM), ``scalar_rgb`` (works everywhere, about 3x slower). A broken
LLVM does not raise: it *aborts the process* (Debian 12's LLVM 15:
"Cannot select: fminimum"), so each candidate is tried in a child process
that renders a tiny scene; only a variant that survived is activated here.

The choice is remembered in the environment variable
``USDCROWD_MITSUBA_VARIANT`` so worker processes inherit it without probing
again; set it yourself to force a variant.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys

from ...core.errors import UsdcrowdError

ENV = "USDCROWD_MITSUBA_VARIANT"
PREFERENCE = ("cuda_ad_rgb", "llvm_ad_rgb", "scalar_rgb")

# Renders a sphere with the path tracer and reads the result back: this touches
# the JIT compiler, Embree/OptiX and the integrator, which is where a broken
# backend fails.
_PROBE = """
import mitsuba as mi
mi.set_variant({variant!r})
scene = mi.load_dict({{"type": "scene", "integrator": {{"type": "path", "max_depth": 3}},
    "s": {{"type": "sphere"}}, "e": {{"type": "constant"}},
    "sensor": {{"type": "perspective", "to_world": mi.ScalarTransform4f().look_at(
        origin=[0, 0, 4], target=[0, 0, 0], up=[0, 1, 0]),
        "film": {{"type": "hdrfilm", "width": 8, "height": 8}}}}}})
img = mi.render(scene, spp=2)
import numpy as np
assert np.isfinite(np.array(img)).all()
print("ok")
"""


def require_mitsuba():
    """Import and return ``mitsuba``, or raise a one-line UsdcrowdError saying what to install."""
    try:
        import drjit  # noqa: F401
        import mitsuba
    except ImportError as exc:
        raise UsdcrowdError(f"final rendering needs Mitsuba ({exc.name} is missing): "
                            "pip install 'usdcrowd[final]'") from None
    return mitsuba


def probe(variant: str, timeout: float = 120.0) -> bool:
    """True if ``variant`` renders a tiny scene in a child process (a crash there is harmless)."""
    try:
        r = subprocess.run([sys.executable, "-c", _PROBE.format(variant=variant)], capture_output=True,
                           text=True, timeout=timeout)
    except (OSError, subprocess.TimeoutExpired):
        return False
    return r.returncode == 0 and r.stdout.strip().endswith("ok")


def choose_variant(requested: str | None = None) -> str:
    """Name of the Mitsuba variant to render with.

    Parameters
    ----------
    requested : str, optional
        A variant name, or "auto"/None for the first of :data:`PREFERENCE`
        that is compiled into this Mitsuba and survives :func:`probe`.

    Returns
    -------
    str
        The variant; also stored in ``os.environ[ENV]`` for child processes.

    Raises
    ------
    UsdcrowdError
        If Mitsuba is missing, the requested variant is not available, or no
        variant works.
    """
    mi = require_mitsuba()
    available = set(mi.variants())
    if requested and requested != "auto":
        if requested not in available:
            raise UsdcrowdError(f"Mitsuba variant {requested!r} is not available "
                                f"(this build has: {', '.join(sorted(available))})")
        return requested
    remembered = os.environ.get(ENV)
    if remembered:
        if remembered not in available:
            raise UsdcrowdError(f"{ENV}={remembered!r} is not a variant of this Mitsuba build")
        return remembered
    for variant in PREFERENCE:
        if variant in available and (variant == "scalar_rgb" or probe(variant)):
            os.environ[ENV] = variant
            return variant
    raise UsdcrowdError("no Mitsuba variant works here (tried " + ", ".join(PREFERENCE) + ")")


def activate(variant: str):
    """Set ``variant`` as Mitsuba's current variant; returns the ``mitsuba`` module."""
    mi = require_mitsuba()
    if mi.variant() != variant:
        mi.set_variant(variant)
    return mi


def is_jit(variant: str) -> bool:
    """True for the vectorised (LLVM/CUDA) variants, where whole images are one array."""
    return not variant.startswith("scalar")


def describe(variant: str) -> str:
    """One line for logs: the variant and what it runs on."""
    where = {"cuda": "GPU (CUDA/OptiX)", "llvm": "CPU (LLVM JIT, all cores)", "scalar": "CPU (scalar, slow)"}
    return f"mitsuba {require_mitsuba().__version__} variant {variant}: {where[variant.split('_')[0]]}"


@contextlib.contextmanager
def single_threaded_build():
    """Build acceleration structures on one thread (scene loading, ``params.update()``).

    Embree builds its BVH on every worker thread; under load the threads
    split the work differently and the tree differs, which moves a few
    intersections in their last bits: 21-49 of 230,400 pixels of a
    640x360 frame differed between identical renders on this 2-core
    machine while another job ran, none with a one-thread build (measured
    over 16 renders each). It costs 0.19 s a frame for the benchmark's 200
    characters at 640x360 (update 0.28 -> 0.47 s, 2.39 -> 2.59 s a frame on
    2 cores, tools/bench.py render); the rays still trace on every thread.
    """
    import drjit as dr

    if not hasattr(dr, "thread_count"):         # scalar and CUDA variants: nothing to pin
        yield
        return
    n = dr.thread_count()
    if n == 1:
        yield
        return
    # The pool is resized only when no kernel is in flight: resizing it under running work hung a test
    # run once (the main thread waiting in set_thread_count, every worker asleep).
    dr.sync_thread()
    dr.set_thread_count(1)
    try:
        yield
    finally:
        dr.sync_thread()
        dr.set_thread_count(n)
