"""Speed of the event detector (seed 000, section 4.1) on one core.

Scene: a square holding ``n`` agents (density about 0.25 per m^2): a third
of them walk in platoons of 20 in formation, the rest wander at random
headings; a few pairs stand face to face. Each frame is fed to the
detector as a whole shot in chunks of 48 frames; the quad-tree group part
(``find_groups``) is also timed alone.

Usage::

    python tools/bench_events.py              # 1,000 and 10,000 agents
    python tools/bench_events.py 100000       # chosen sizes
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from usdcrowd.events import EventDetector, EventParams, find_groups  # noqa: E402
from usdcrowd.core.model import CrowdFrames

FPS = 24.0
FRAMES = 96
CHUNK = 48


def scene(n: int, frames: int = FRAMES, seed: int = 0) -> CrowdFrames:
    """(frames, n) tracks: platoons of 20 in formation, wanderers, face-to-face pairs."""
    rng = np.random.default_rng(seed)
    half = np.sqrt(n / 0.25) / 2
    dt = 1.0 / FPS
    n_pl = (n // 3) // 20
    n_pairs = min(n // 100, 50)
    n_wa = n - 20 * n_pl - 2 * n_pairs
    pos = np.empty((frames, n, 2))
    vel = np.empty((frames, n, 2))
    head = np.empty((frames, n))
    # Platoons: 4 x 5 at 1 m, each with its own direction.
    ij = np.stack(np.meshgrid(np.arange(5), np.arange(4), indexing="ij"), -1).reshape(-1, 2) - (2, 1.5)
    c0 = rng.uniform(-half, half, (n_pl, 2))
    ang = rng.uniform(-np.pi, np.pi, n_pl)
    d = np.stack([np.cos(ang), np.sin(ang)], 1)
    t = np.arange(frames)[:, None, None] * dt
    cen = c0[None] + 1.3 * d[None] * t  # (f, p, 2)
    rot = np.stack([np.stack([d[:, 0], -d[:, 1]], 1), np.stack([d[:, 1], d[:, 0]], 1)], 1)  # (p, 2, 2)
    off = np.einsum("pij,kj->pki", rot, ij.astype(float))  # (p, 20, 2)
    k = 20 * n_pl
    pos[:, :k] = (cen[:, :, None] + off[None]).reshape(frames, k, 2)
    vel[:, :k] = np.repeat(1.3 * d, 20, axis=0)[None]
    head[:, :k] = np.repeat(ang, 20)[None]
    # Wanderers: drifting headings.
    w0 = rng.uniform(-half, half, (n_wa, 2))
    h = rng.uniform(-np.pi, np.pi, n_wa) + np.cumsum(rng.normal(0, 0.6 * np.sqrt(dt), (frames, n_wa)), 0)
    s = rng.uniform(0.8, 1.6, n_wa)
    v = s[None, :, None] * np.stack([np.cos(h), np.sin(h)], -1)
    pos[:, k:k + n_wa] = w0 + np.cumsum(v * dt, 0)
    vel[:, k:k + n_wa] = v
    head[:, k:k + n_wa] = h
    # Face-to-face pairs, standing.
    a = rng.uniform(-half, half, (n_pairs, 2))
    pos[:, k + n_wa::2] = a
    pos[:, k + n_wa + 1::2] = a + (1.2, 0)
    vel[:, k + n_wa:] = 0
    head[:, k + n_wa::2] = 0
    head[:, k + n_wa + 1::2] = np.pi
    z = np.zeros((frames, n, 1))
    return CrowdFrames(times=1.0 + np.arange(frames), position=np.concatenate([pos, z], 2).astype(np.float32),
                       heading=head.astype(np.float32), velocity=vel.astype(np.float32),
                       behavior=np.zeros((frames, n), np.int8), anim_class=np.zeros((frames, n), np.int8),
                       anim_phase=np.zeros((frames, n), np.float32), health=np.zeros((frames, n), np.int8),
                       look_at=np.full((frames, n, 3), np.nan, np.float32), path_method=np.zeros(n, np.int8))


def bench(n: int) -> None:
    fr = scene(n)
    ctype = np.zeros(n, np.int8)
    p = EventParams()
    # The quad-tree group part alone.
    xy = fr.position[:, :, :2].astype(np.float64)
    vel = fr.velocity.astype(np.float64)
    find_groups(xy[0], vel[0], ctype, p)
    t0 = time.perf_counter()
    for i in range(FRAMES):
        find_groups(xy[i], vel[i], ctype, p)
    t_groups = time.perf_counter() - t0
    # The whole detector, fed in chunks.
    t0 = time.perf_counter()
    det = EventDetector(ctype, np.ones(n, bool), FPS, p)
    for a in range(0, FRAMES, CHUNK):
        b = a + CHUNK
        det.feed(CrowdFrames(fr.times[a:b], fr.position[a:b], fr.heading[a:b], fr.velocity[a:b],
                             fr.behavior[a:b], fr.anim_class[a:b], fr.anim_phase[a:b], fr.health[a:b],
                             fr.look_at[a:b], fr.path_method))
    table = det.finish()
    t_all = time.perf_counter() - t0
    kinds = np.bincount([e.kind for e in table], minlength=2)
    print(f"{n:>7} agents: groups (quad-tree) {FRAMES / t_groups:7.1f} frames/s "
          f"({1e3 * t_groups / FRAMES:6.2f} ms/frame); whole detector {FRAMES / t_all:7.1f} frames/s "
          f"({1e3 * t_all / FRAMES:6.2f} ms/frame); events: {kinds[0]} interactions, {kinds[1]} group motions")


if __name__ == "__main__":
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    sizes = [int(a) for a in sys.argv[1:]] or [1000, 10000]
    for n in sizes:
        bench(n)
