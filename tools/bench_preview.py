"""Frames per second of the OpenGL preview at 1280x720, 1,000 and 10,000 characters.

    .venv/bin/python tools/bench_preview.py [--frames 12] [--rounds 3] [--workdir DIR] [--scenes museum:1000,volcano:10000]

Builds shots with ``usdcrowd new TEMPLATE --agents N`` and
``usdcrowd simulate`` (kept in --workdir for the next run), reads the poses
of a few frames first (stage loading is not timed), then times drawing plus
reading back colour, ids and depth, from each of the shot's cameras, with
the default level of detail, with shadows off, and with every character at
its full mesh for reference, and the same frames with no characters (the
floor: the scenery, shadows and read-back alone), each setting's frame cost
printed as a multiple of that empty frame's. The empty frame and the two
level-of-detail settings are timed in interleaved rounds and their medians
kept, so the ratio does not ride on a burst of load. Headless EGL; on a machine without a GPU that
is Mesa's llvmpipe, whose speed depends on the cores it can use.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np


SIZE = (1280, 720)
# (template, characters). The 10,000-character target is measured on two
# scenes: the museum (seed 003's scene, 600 m^2, so 17 people per m^2 at
# 10,000: denser than any real crowd, the worst case for overdraw) and the
# volcano (seed 004's 160 m x 160 m terrain, where that paper reports its
# 10,000-character figure).
SCENES = (("museum", 1_000), ("museum", 10_000), ("volcano", 10_000))
TARGET_AGENTS = 10_000
TARGET_FPS = 24.0
TARGET_OVER_EMPTY = 2.0     # a frame with 10,000 characters costs at most twice the frame without them
# At 10,000 characters the empty frame and the crowd are timed again at a sixteenth of the pixels: what
# the crowd adds there and at SIZE tells a cost per character (vertices, triangle set-up) from one per pixel.
SMALL = (320, 180)
ROUNDS = 3


def make_shot(n_agents: int, workdir: Path, frames: int, template: str = "museum") -> Path:
    """A simulated shot of ``template`` with ``n_agents`` (reused when it exists)."""
    from usdcrowd.cli import main

    shot = workdir / f"{template}_{n_agents}" / "shot.usda"
    if not shot.exists():
        scenario = workdir / f"{template}_{n_agents}.usda"
        assert main(["new", template, "-o", str(scenario), "--agents", str(n_agents)]) == 0
        assert main(["simulate", str(scenario), "-o", str(shot.parent), "--frames", f"1:{frames}",
                     "--no-progress"]) == 0
    return shot


def time_renderer(renderer, poses_by_time, cameras, repeats: int = 1) -> tuple[float, dict]:
    """Frames per second of draw + read-back over the given poses and cameras; last frame's stats."""
    n = 0
    stats = {}
    t0 = time.perf_counter()
    for _ in range(repeats):
        for t, poses in poses_by_time.items():
            stats = renderer.render_poses(poses, cameras[t]).stats
            n += 1
    return n / (time.perf_counter() - t0), stats


def warm_up(renderer, poses_by_time, cameras) -> None:
    """Draw one frame untimed: shader compilation, buffers."""
    first = next(iter(poses_by_time.values()))
    renderer.render_poses(first, cameras[float(first.time)])


def run(frames: int = 8, workdir: str | os.PathLike | None = None, scenes=SCENES, rounds: int = ROUNDS) -> dict:
    """Print and return frames per second for each scene, camera and setting."""
    import usdcrowd  # noqa: F401
    from usdcrowd.render.preview import LodSettings, PreviewRenderer
    from usdcrowd.scenario.shot_scene import ShotScene

    workdir = Path(workdir or Path(tempfile.gettempdir()) / "usdcrowd_bench_preview")
    workdir.mkdir(parents=True, exist_ok=True)
    results = {}
    print(f"preview benchmark: {SIZE[0]}x{SIZE[1]}, draw + read-back of colour, ids and depth, "
          f"{os.cpu_count()} CPUs; the empty frame, level of detail and no shadows timed in {rounds} "
          f"interleaved rounds (median), full meshes once")
    for template, n in scenes:
        shot = make_shot(n, workdir, frames, template)
        scene = ShotScene(shot)
        t0 = time.perf_counter()
        times = scene.time_codes[:frames]
        poses = {float(t): scene.agents(t) for t in times}
        load_s = time.perf_counter() - t0
        probe = PreviewRenderer(scene, *SIZE)
        renderer_info = probe.ctx.info["GL_RENDERER"]
        no_shadows = PreviewRenderer(scene, *SIZE, ctx=probe.ctx, shadows=False)
        small = PreviewRenderer(scene, *SMALL, ctx=probe.ctx) if n >= TARGET_AGENTS else None
        for cam_path in scene.camera_paths:
            cams = {float(t): scene.camera(cam_path, t) for t in times}
            nobody = {t: replace(p, visible=np.zeros(len(p), bool)) for t, p in poses.items()}
            # Interleaved, so a burst of load on the machine falls on every setting alike.
            settings = {"empty": (probe, nobody), "lod": (probe, poses), "lod, no shadows": (no_shadows, poses)}
            if small is not None:
                at = size_label(SMALL)
                settings.update({f"empty, {at}": (small, nobody), f"lod, {at}": (small, poses)})
            for r, ps in settings.values():
                warm_up(r, ps, cams)
            samples = {label: [] for label in settings}
            for _ in range(rounds):
                for label, (r, ps) in settings.items():
                    fps, stats = time_renderer(r, ps, cams)
                    samples[label].append(fps)
                    if label == "lod":
                        lod_stats = stats
            cam = cam_path.rsplit('/', 1)[-1]
            empty = results[(template, n, cam_path, "empty")] = float(np.median(samples["empty"]))
            print(f"  {template:<8} {n:>6,} characters  {cam:<10} {'no characters':<16} {empty:6.2f} fps")
            full = PreviewRenderer(scene, *SIZE, ctx=probe.ctx, lod_settings=LodSettings(enabled=False))
            warm_up(full, poses, cams)
            measured = {"lod": (float(np.median(samples["lod"])), lod_stats),
                        "lod, no shadows": (float(np.median(samples["lod, no shadows"])), lod_stats),
                        "full meshes": time_renderer(full, poses, cams)}
            full.release()
            for label, (fps, stats) in measured.items():
                results[(template, n, cam_path, label)] = fps
                print(f"  {template:<8} {n:>6,} characters  {cam:<10} {label:<16} "
                      f"{fps:6.2f} fps, {empty / fps:5.2f}x the empty frame  (full {stats['full']}, "
                      f"clustered {stats['coarse']}, "
                      f"impostors {stats.get('impostors', 0)}, points {stats['points']}, culled {stats['culled']})")
            if small is not None:
                _print_small(results, samples, template, n, cam_path)
        no_shadows.release()
        if small is not None:
            small.release()
        probe.release()
        print(f"  ({template}, {n:,} characters: reading {len(times)} frames of poses from the stage took "
              f"{load_s:.1f} s, not timed; renderer {renderer_info})")
    for template, n in scenes:
        if n < TARGET_AGENTS:
            continue
        worst = min(v for (tp, m, _, lbl), v in results.items() if (tp, m) == (template, n) and lbl == "lod")
        verdict = "meets" if worst >= TARGET_FPS else "is under"
        print(f"target: >= {TARGET_FPS:g} fps for {n:,} characters with level of detail and shadows; "
              f"{template}: slowest camera {worst:.2f} fps {verdict} it")
        over = over_empty(results, template, n)
        print(f"target: a frame with {n:,} characters (level of detail, shadows) at most {TARGET_OVER_EMPTY:g}x the "
              f"same frame without them; {template}: {over:.2f}x at the worst camera "
              f"({'met' if over <= TARGET_OVER_EMPTY else 'not met'})")
    return results


def size_label(wh) -> str:
    """``1280x720`` for (1280, 720)."""
    return f"{wh[0]}x{wh[1]}"


def _print_small(results: dict, samples: dict, template: str, n: int, cam_path: str) -> None:
    """Keep the small frame's medians in ``results`` and print what the crowd adds at either size."""
    cam = cam_path.rsplit('/', 1)[-1]
    for label in ("empty", "lod"):
        key = f"{label}, {size_label(SMALL)}"
        results[(template, n, cam_path, key)] = float(np.median(samples[key]))
    added = crowd_ms(results, template, n, cam_path)
    print(f"  {template:<8} {n:>6,} characters  {cam:<10} the crowd adds {added[size_label(SIZE)]:.1f} ms a frame at "
          f"{size_label(SIZE)}, {added[size_label(SMALL)]:.1f} ms at {size_label(SMALL)} (a sixteenth of the pixels)")


def crowd_ms(results: dict, template: str, n: int, cam_path: str) -> dict:
    """Milliseconds the crowd (level of detail, shadows) adds to a frame of ``cam_path`` at SIZE and at
    SMALL, from :func:`run`'s results: ``{"1280x720": ms, "320x180": ms}``."""
    out = {}
    for size, suffix in ((SIZE, ""), (SMALL, f", {size_label(SMALL)}")):
        lod, empty = (results[(template, n, cam_path, label + suffix)] for label in ("lod", "empty"))
        out[size_label(size)] = 1e3 / lod - 1e3 / empty
    return out


def over_empty(results: dict, template: str, n: int) -> float:
    """A scene's worst camera: its frame with characters (level of detail, shadows) over the same frame empty,
    from :func:`run`'s results."""
    return max(results[(tp, m, cam, "empty")] / fps for (tp, m, cam, label), fps in results.items()
               if (tp, m) == (template, n) and label == "lod")


def _scenes(text: str) -> tuple:
    out = []
    for item in text.split(","):
        template, _, n = item.partition(":")
        out.append((template, int(n)))
    return tuple(out)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--frames", type=int, default=8, help="frames timed per camera (default 8)")
    p.add_argument("--rounds", type=int, default=ROUNDS, help=f"interleaved rounds (default {ROUNDS})")
    p.add_argument("--workdir", help="where the benchmark shots are kept")
    p.add_argument("--scenes", type=_scenes, default=SCENES,
                   help="TEMPLATE:CHARACTERS, comma-separated (default "
                        + ",".join(f"{t}:{n}" for t, n in SCENES) + ")")
    a = p.parse_args(argv)
    run(a.frames, a.workdir, a.scenes, a.rounds)
    return 0


if __name__ == "__main__":
    sys.exit(main())
