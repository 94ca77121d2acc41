"""Frames per second of the OpenGL preview at 1280x720, 1,000 and 10,000 characters.

    .venv/bin/python tools/bench_preview.py [--frames 12] [--workdir DIR]

Builds museum shots with ``usdcrowd new museum --agents N`` and
``usdcrowd simulate`` (kept in --workdir for the next run), reads the poses
of a few frames first (stage loading is not timed), then times drawing plus
reading back colour, ids and depth, from both of the shot's cameras, with
the default level of detail, with shadows off, and with every character at
its full mesh for reference. Headless EGL; on a machine without a GPU that
is Mesa's llvmpipe, whose speed depends on the cores it can use.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path


SIZE = (1280, 720)
COUNTS = (1_000, 10_000)
TARGET_FPS = 24.0


def make_shot(n_agents: int, workdir: Path, frames: int) -> Path:
    """A simulated museum shot with ``n_agents`` (reused when it exists)."""
    from usdcrowd.cli import main

    shot = workdir / f"museum_{n_agents}" / "shot.usda"
    if not shot.exists():
        scenario = workdir / f"museum_{n_agents}.usda"
        assert main(["new", "museum", "-o", str(scenario), "--agents", str(n_agents)]) == 0
        assert main(["simulate", str(scenario), "-o", str(shot.parent), "--frames", f"1:{frames}",
                     "--no-progress"]) == 0
    return shot


def time_renderer(renderer, poses_by_time, cameras, repeats: int = 1) -> tuple[float, dict]:
    """Frames per second of draw + read-back over the given poses and cameras; last frame's stats."""
    first = next(iter(poses_by_time.values()))
    renderer.render_poses(first, cameras[float(first.time)])          # warm-up: shader compile, buffers
    n = 0
    stats = {}
    t0 = time.perf_counter()
    for _ in range(repeats):
        for t, poses in poses_by_time.items():
            stats = renderer.render_poses(poses, cameras[t]).stats
            n += 1
    return n / (time.perf_counter() - t0), stats


def run(frames: int = 8, workdir: str | os.PathLike | None = None, counts=COUNTS) -> dict:
    """Print and return frames per second for each character count and setting."""
    import usdcrowd  # noqa: F401
    from usdcrowd.render.preview import LodSettings, PreviewRenderer
    from usdcrowd.render.scene import ShotScene

    workdir = Path(workdir or Path(tempfile.gettempdir()) / "usdcrowd_bench_preview")
    workdir.mkdir(parents=True, exist_ok=True)
    results = {}
    print(f"preview benchmark: {SIZE[0]}x{SIZE[1]}, draw + read-back of colour, ids and depth, "
          f"{os.cpu_count()} CPUs")
    for n in counts:
        shot = make_shot(n, workdir, frames)
        scene = ShotScene(shot)
        t0 = time.perf_counter()
        times = scene.time_codes[:frames]
        poses = {float(t): scene.agents(t) for t in times}
        load_s = time.perf_counter() - t0
        probe = PreviewRenderer(scene, *SIZE)
        renderer_info = probe.ctx.info["GL_RENDERER"]
        for cam_path in scene.camera_paths:
            cams = {float(t): scene.camera(cam_path, t) for t in times}
            for label, kwargs in (("lod", {}), ("lod, no shadows", {"shadows": False}),
                                  ("full meshes", {"lod_settings": LodSettings(enabled=False)})):
                r = probe if label == "lod" else PreviewRenderer(scene, *SIZE, ctx=probe.ctx, **kwargs)
                fps, stats = time_renderer(r, poses, cams)
                results[(n, cam_path, label)] = fps
                print(f"  {n:>6,} characters  {cam_path.rsplit('/', 1)[-1]:<10} {label:<16} {fps:6.2f} fps  "
                      f"(full {stats['full']}, clustered {stats['coarse']}, impostors {stats.get('impostors', 0)}, "
                      f"points {stats['points']}, "
                      f"culled {stats['culled']})")
                if r is not probe:
                    r.release()
        probe.release()
        print(f"  ({n:,} characters: reading {len(times)} frames of poses from the stage took {load_s:.1f} s, "
              f"not timed; renderer {renderer_info})")
    best10k = max((v for (n, _, lbl), v in results.items() if n == max(counts) and lbl.startswith("lod")),
                  default=float("nan"))
    verdict = "meets" if best10k >= TARGET_FPS else "is under"
    print(f"target: >= {TARGET_FPS:g} fps for {max(counts):,} characters with level of detail; "
          f"best measured {best10k:.2f} fps {verdict} it")
    return results


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--frames", type=int, default=8, help="frames timed per camera (default 8)")
    p.add_argument("--workdir", help="where the benchmark shots are kept")
    p.add_argument("--counts", type=lambda s: tuple(int(x) for x in s.split(",")), default=COUNTS,
                   help="character counts, comma-separated (default 1000,10000)")
    a = p.parse_args(argv)
    run(a.frames, a.workdir, a.counts)
    return 0


if __name__ == "__main__":
    sys.exit(main())
