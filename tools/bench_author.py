"""Authoring a crowd as USD against plain Sdf writing the same samples (the floor).

Three rows, measured in the same run in interleaved rounds (medians and the
median of the per-round ratios are reported):

- **floor**: plain Sdf, no usdcrowd code: two processes (as usdcrowd's part
  writers on a two-core machine), each writing its half of the agents as
  layers of 1,000 agents: per agent a SkelRoot and its SkelAnimation, the
  rotations and translations of every frame and the three state tokens
  where they change, exactly the samples usdcrowd writes (computed before
  the clock starts and read from memory-mapped files), saved as ``.usdc``.
- **crowd layer**: usdcrowd's :class:`~usdcrowd.usd.CrowdLayerWriter` fed the
  crowd's frames a chunk at a time: the same split, plus what usdcrowd
  writes beside the samples (every agent's attributes, prototypes,
  materials) and the animation that makes the samples.
- **crowd layer, in windows**: the same with the samples in value-clip windows of
  WINDOW frames (what a longer shot or a larger crowd is written as: what the
  windows cost, and what they save in memory).
- **shot**: ``author_shot``, what ``simulate`` does after simulating: the
  crowd layer, the camera agents, the overview and the trajectory map (the
  crowd's frames come from a straight walk, not a simulation); once more
  with event detection (``simulate``'s default), measured once after the rounds.

Then, each timed alone in one process, what a writer does besides the floor's
work: its agents' prims and attributes, and their animation.

Targets: the crowd layer within 1.25x of the floor; the shot in 20 s and
4 GiB (10,000 agents x 300 frames on two cores).

Each row runs in a fresh interpreter; its peak memory is the coordinator's
peak resident set plus the largest writer's.
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CHUNK = 50                  # frames per chunk handed to the writers, as simulate does
WORKERS = 2
PER_LAYER = 1000
TARGET_RATIO = 1.25         # crowd layer within 1.25x of the floor
WINDOW = 80                 # frames per clip window in the windowed row
TARGET_SHOT_S = 20.0        # 10,000 agents x 300 frames as a shot
TARGET_SHOT_GIB = 4.0


def _peak_mib() -> float:
    """Peak resident memory of this process plus the largest of its finished children (the writers)."""
    own = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    children = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    return (own + children) / 1024.0


def _scenario(folder: Path, agents: int) -> Path:
    from usdcrowd.jobs.templates import new_scenario

    path = folder / "scenario.usda"
    if not path.exists():
        new_scenario("museum", path, agents=agents, seed=1)
    return path


def _chunks(scenario, whole):
    from usdcrowd.core import model

    for s in range(0, len(whole.times), CHUNK):
        sl = slice(s, s + CHUNK)
        yield model.CrowdFrames(whole.times[sl], whole.position[sl], whole.heading[sl], whole.velocity[sl],
                                whole.behavior[sl], whole.anim_class[sl], whole.anim_phase[sl],
                                whole.health[sl], whole.look_at[sl], whole.path_method)


def _read(folder: Path, agents: int, frames: int):
    from tests.helpers.frames import straight_walk

    from usdcrowd.jobs.pipeline import _read_scenario

    stage, scenario = _read_scenario(os.fspath(_scenario(folder, agents)), None, (1, frames), None)
    return stage, scenario, straight_walk(scenario.agents, scenario.time)


def write_samples(folder: Path, agents: int, frames: int) -> dict:
    """usdcrowd's samples for the floor, as ``.npy`` files in ``folder`` (not timed).

    The animation is usdcrowd's own (:class:`~usdcrowd.character.animation.Animator`
    and the root motion, chunk by chunk as the part writers run them), so the
    floor writes the very values usdcrowd writes.
    """
    from usdcrowd.character import rig
    from usdcrowd.character.animation import Animator
    from usdcrowd.character.root import apply_root_motion
    from usdcrowd.usd.crowd_layer import _TOKEN_SLOTS

    folder = Path(folder)
    _, scenario, whole = _read(folder, agents, frames)
    n, t = len(scenario.agents), len(whole.times)
    rot = np.lib.format.open_memmap(folder / "rot.npy", "w+", np.float32, (t, n, 3, 4))
    trans = np.lib.format.open_memmap(folder / "trans.npy", "w+", np.float32, (t, n, 3, 3))
    animator = Animator(1.0 / scenario.time.fps, scenario.agents.height)
    for k, chunk in enumerate(_chunks(scenario, whole)):
        r, tr = animator(chunk)
        r, tr, _ = apply_root_motion(r, tr, chunk.position, chunk.heading, scenario.agents.height)
        rot[k * CHUNK:k * CHUNK + len(chunk.times)] = rig.to_usd_quat_order(r)
        trans[k * CHUNK:k * CHUNK + len(chunk.times)] = tr
    rot.flush()
    trans.flush()
    for key, _ in _TOKEN_SLOTS:
        np.save(folder / f"{key}.npy", np.asarray(getattr(whole, key), np.int8))
    np.save(folder / "times.npy", np.asarray(whole.times, np.float64))
    meta = {"paths": list(scenario.agents.path), "vocab": {key: list(v) for key, v in _TOKEN_SLOTS}}
    (folder / "meta.json").write_text(json.dumps(meta))
    return {"agents": n, "frames": t}


def floor_worker(folder: str, first: int, last: int, out: str) -> None:
    """One floor process: agents ``first:last`` as layers of PER_LAYER agents in ``out``. Plain Sdf only."""
    from pxr import Sdf, Vt

    folder = Path(folder)
    meta = json.loads((folder / "meta.json").read_text())
    times = [float(x) for x in np.load(folder / "times.npy")]
    rot = np.load(folder / "rot.npy", mmap_mode="r")
    trans = np.load(folder / "trans.npy", mmap_mode="r")
    tokens = {key: np.load(folder / f"{key}.npy", mmap_mode="r") for key in meta["vocab"]}
    names = {"behavior": "crowd:state:behavior", "anim_class": "crowd:state:animClass",
             "health": "crowd:state:health"}
    T = Sdf.ValueTypeNames
    n_t = len(times)
    slices = [slice(k * 3, (k + 1) * 3) for k in range(n_t)]
    for start in range(first, last, PER_LAYER):
        rows = np.arange(start, min(start + PER_LAYER, last))
        layer = Sdf.Layer.CreateAnonymous(".usdc")
        layer.startTimeCode, layer.endTimeCode = times[0], times[-1]
        r = np.ascontiguousarray(np.swapaxes(rot[:, rows], 0, 1)).reshape(len(rows), n_t * 3, 4)
        tr = np.ascontiguousarray(np.swapaxes(trans[:, rows], 0, 1)).reshape(len(rows), n_t * 3, 3)
        with Sdf.ChangeBlock():
            for j, i in enumerate(rows):
                path = meta["paths"][i]
                root = Sdf.CreatePrimInLayer(layer, path)
                root.specifier, root.typeName = Sdf.SpecifierDef, "SkelRoot"
                anim = Sdf.PrimSpec(root, "Anim", Sdf.SpecifierDef, "SkelAnimation")
                rpath = Sdf.AttributeSpec(anim, "rotations", T.QuatfArray).path
                tpath = Sdf.AttributeSpec(anim, "translations", T.Float3Array).path
                r_j, t_j = Vt.QuatfArray.FromNumpy(r[j]), Vt.Vec3fArray.FromNumpy(tr[j])
                for t, k in zip(times, slices):
                    layer.SetTimeSample(rpath, t, r_j[k])
                    layer.SetTimeSample(tpath, t, t_j[k])
                for key, vocab in meta["vocab"].items():
                    apath = Sdf.AttributeSpec(root, names[key], T.Token).path
                    values = tokens[key][:, i]
                    for k in np.flatnonzero(np.r_[True, values[1:] != values[:-1]]):
                        layer.SetTimeSample(apath, times[k], vocab[values[k]])
        layer.Export(os.path.join(out, f"floor.part{start // PER_LAYER:03d}.usdc"))


def floor_once(folder: str, agents: int) -> dict:
    """The floor: WORKERS processes started together, timed until both have saved."""
    out = tempfile.mkdtemp(dir=folder)
    bounds = np.linspace(0, agents, WORKERS + 1).astype(int)
    # Each process's share rounded to whole layers, as usdcrowd splits (array_split, then layers of ~1,000).
    code = ("import sys; sys.path[:0] = [{root!r}, {tools!r}]; import bench_author; "
            "bench_author.floor_worker({folder!r}, {first}, {last}, {out!r})")
    t0 = time.perf_counter()
    procs = [subprocess.Popen([sys.executable, "-c", code.format(root=str(ROOT), tools=str(ROOT / "tools"),
                                                                 folder=folder, first=int(a), last=int(b), out=out)])
             for a, b in zip(bounds[:-1], bounds[1:])]
    codes = [p.wait() for p in procs]
    seconds = time.perf_counter() - t0
    if any(codes):
        raise RuntimeError(f"a floor writer failed (exit codes {codes})")
    return {"seconds": seconds, "peak_mib": _peak_mib(), "size_mib": _size_mib(out)}


def crowd_layer_once(folder: str, agents: int, frames: int, clip_frames: int | None = None) -> dict:
    """usdcrowd's CrowdLayerWriter over the same frames (timed from the writer's start to its save), its
    samples in value-clip windows of ``clip_frames`` frames if given (else as the writer decides)."""
    from usdcrowd.scenario import stage_frame
    from usdcrowd.usd import CrowdLayerWriter

    stage, scenario, whole = _read(Path(folder), agents, frames)
    out = Path(tempfile.mkdtemp(dir=folder))
    default_prim = stage.GetDefaultPrim().GetName()
    t0 = time.perf_counter()
    writer = CrowdLayerWriter(out / "crowd.usdc", scenario, stage_frame(stage), default_prim, "scenario.usda",
                              set(), workers=WORKERS, clip_frames=clip_frames)
    for chunk in _chunks(scenario, whole):
        writer.write_chunk(chunk)
    writer.save()
    seconds = time.perf_counter() - t0
    return {"seconds": seconds, "peak_mib": _peak_mib(), "size_mib": _size_mib(out)}


def shot_once(folder: str, agents: int, frames: int, events: bool = False) -> dict:
    """``author_shot`` (crowd layer, cameras, overview, map) over the same frames, with or without event
    detection."""
    from tests.helpers.frames import straight_walk

    from usdcrowd.jobs.pipeline import author_shot

    scenario = _scenario(Path(folder), agents)
    out = Path(tempfile.mkdtemp(dir=folder)) / "shot"
    t0 = time.perf_counter()
    author_shot(scenario, out, lambda sc: _chunks(sc, straight_walk(sc.agents, sc.time)), frames=(1, frames),
                progress=False, events=events)
    seconds = time.perf_counter() - t0
    return {"seconds": seconds, "peak_mib": _peak_mib(), "size_mib": _size_mib(out)}


def extras_once(folder: str, agents: int, frames: int) -> dict:
    """What one writer does besides the floor's work, each timed alone in this process: its agents' prims
    and attributes (as its part layers hold them, not saved) and their animation (pose, blends, look-at and
    root motion over every chunk; the first call's loading of the compiled code included, as in a writer)."""
    from pxr import Sdf

    from usdcrowd.character.animation import Animator
    from usdcrowd.character.kernels import root_motion
    from usdcrowd.character.root import root_scale
    from usdcrowd.scenario import stage_frame
    from usdcrowd.usd.crowd_layer import _AgentPart

    stage, scenario, whole = _read(Path(folder), agents, frames)
    share = np.array_split(np.arange(len(scenario.agents)), WORKERS)[0]
    parts = np.array_split(share, max(1, round(len(share) / PER_LAYER)))
    t0 = time.perf_counter()
    for rows in parts:
        _AgentPart(Sdf.Layer.CreateAnonymous(".usdc"), scenario, stage_frame(stage), rows, set(),
                   default_prim=stage.GetDefaultPrim().GetName())
    prims = time.perf_counter() - t0
    t0 = time.perf_counter()
    for rows in parts:
        animator = Animator(1.0 / scenario.time.fps, scenario.agents.height[rows])
        scale = root_scale(scenario.agents.height[rows])
        for chunk in _chunks(scenario, whole):
            part = chunk.agents(rows)
            root_motion(*animator(part), part.position, part.heading, scale)
    return {"agents": int(len(share)), "prims_s": prims, "animation_s": time.perf_counter() - t0}


def _size_mib(folder: Path) -> float:
    """What a row wrote, clip folders included."""
    return sum(f.stat().st_size for f in Path(folder).rglob("*") if f.is_file()) / 2 ** 20


def _child(function: str, **kw) -> dict:
    code = (f"import sys, json; sys.path[:0] = [{str(ROOT)!r}, {str(ROOT / 'tools')!r}]; import bench_author; "
            f"print(json.dumps(bench_author.{function}(**{kw!r})))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    if out.returncode != 0:
        raise RuntimeError(out.stderr[-2000:])
    return json.loads(out.stdout.strip().splitlines()[-1])


def run(agents: int = 10_000, frames: int = 300, rounds: int = 3) -> dict:
    """Measure the three rows in ``rounds`` interleaved rounds; print and return them.

    Returns
    -------
    dict
        ``floor``, ``crowd_layer``, ``shot``: median seconds, peak MiB, file MiB and every round's
        seconds; ``ratio_crowd_layer`` / ``ratio_shot``: medians of the per-round ratios to the floor.
    """
    rows = ("floor", "crowd_layer", "crowd_layer_windows", "shot")
    with tempfile.TemporaryDirectory() as tmp:
        size = _child("write_samples", folder=tmp, agents=agents, frames=frames)
        print(f"   {size['agents']:,} agents x {size['frames']} frames, {2 * size['agents'] * size['frames']:,} "
              f"joint samples; {WORKERS} writer processes, layers of {PER_LAYER:,} agents; {rounds} rounds")
        seen: dict = {row: [] for row in rows}
        for _ in range(rounds):
            seen["floor"].append(_child("floor_once", folder=tmp, agents=size["agents"]))
            seen["crowd_layer"].append(_child("crowd_layer_once", folder=tmp, agents=agents, frames=frames))
            seen["crowd_layer_windows"].append(_child("crowd_layer_once", folder=tmp, agents=agents, frames=frames,
                                                      clip_frames=WINDOW))
            seen["shot"].append(_child("shot_once", folder=tmp, agents=agents, frames=frames))
        events = _child("shot_once", folder=tmp, agents=agents, frames=frames, events=True)
        extras = _child("extras_once", folder=tmp, agents=agents, frames=frames)
    found = {"agents": size["agents"], "frames": size["frames"], "rounds": rounds, "window": WINDOW}
    for row in rows:
        s = [r["seconds"] for r in seen[row]]
        found[row] = {"seconds": float(np.median(s)), "each_s": s, "peak_mib": max(r["peak_mib"] for r in seen[row]),
                      "size_mib": seen[row][-1]["size_mib"]}
    for row in ("crowd_layer", "crowd_layer_windows", "shot"):
        found[f"ratio_{row}"] = float(np.median([a["seconds"] / f["seconds"]
                                                 for a, f in zip(seen[row], seen["floor"])]))
    print(f"   {'row':<22} {'median s':>9} {'rounds (s)':<22} {'peak MiB':>9} {'files MiB':>10} {'x floor':>8}")
    for row in rows:
        r = found[row]
        ratio = f"{found[f'ratio_{row}']:8.2f}" if row != "floor" else f"{1.0:8.2f}"
        print(f"   {row:<22} {r['seconds']:9.2f} {', '.join(f'{x:.1f}' for x in r['each_s']):<22} "
              f"{r['peak_mib']:9,.0f} {r['size_mib']:10.1f} {ratio}")
    found["shot_with_events"] = {k: events[k] for k in ("seconds", "peak_mib", "size_mib")}
    found["extras"] = extras
    print(f"   what one writer ({extras['agents']:,} agents) does besides the floor's work, each timed alone: "
          f"its agents' prims and attributes {extras['prims_s']:.2f} s, their animation {extras['animation_s']:.2f} s")
    print(f"   shot with event detection (simulate's default): {events['seconds']:.2f} s "
          f"({events['seconds'] / found['shot']['seconds']:.2f}x the shot without), peak {events['peak_mib']:,.0f} MiB")
    print(f"   target: crowd layer within {TARGET_RATIO}x of the floor: {found['ratio_crowd_layer']:.2f}x "
          f"({'met' if found['ratio_crowd_layer'] <= TARGET_RATIO else 'not met'})")
    shot = found["shot"]
    print(f"   target: shot <= {TARGET_SHOT_S:.0f} s: {shot['seconds'] / TARGET_SHOT_S:.2f}x of budget; "
          f"<= {TARGET_SHOT_GIB:.0f} GiB: {shot['peak_mib'] / 1024 / TARGET_SHOT_GIB:.2f}x of budget")
    return found


if __name__ == "__main__":
    run(*(int(a) for a in sys.argv[1:3]))
