"""Long shots split over time: value clips hold the same animation as one layer, for every reader."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from pxr import Sdf, Usd, Vt

from tests.helpers.frames import straight_walk
from usdcrowd.core import model
from usdcrowd.atomic import output_dir
from usdcrowd.core.errors import StageError
from usdcrowd.jobs.pipeline import author_shot
from usdcrowd.scenario import StageFrame, load_scenario, open_stage
from usdcrowd.scenario.crowd import read_crowd
from usdcrowd.usd import clips, crowd_layer
from usdcrowd.jobs.validation import validate

FRAMES = (1, 30)
WINDOW = 7          # windows 1-7, 8-14, 15-21, 22-28, 29-30


def _chunks(frames: model.CrowdFrames, size: int):
    """The frames in chunks of ``size`` (which straddle the clip windows)."""
    for s in range(0, len(frames.times), size):
        sl = slice(s, s + size)
        yield frames.frames(sl)


def _wandering(sc):
    """Agents walking straight, with behaviors that change now and then (token samples)."""
    frames = straight_walk(sc.agents, sc.time)
    rng = np.random.default_rng(3)
    frames.behavior[:] = np.repeat(rng.integers(0, 3, (len(frames.times) // 4 + 1, len(sc.agents))), 4, 0)[
        :len(frames.times)]
    yield from _chunks(frames, 5)


@pytest.fixture
def shots(tmp_path, museum_path):
    """The museum over 30 frames authored twice: in one layer, and in 7-frame clip windows."""
    made = {}
    for name, window in (("inline", None), ("clipped", WINDOW)):
        made[name] = author_shot(museum_path, tmp_path / name, _wandering, frames=FRAMES, progress=False,
                                 events=False, clip_frames=window)
    return made


def test_windows_split_the_frames():
    plan = clips.ClipPlan(1.0, 30.0, 7, "/x", "./c")
    assert plan.n_windows == 5 and clips.ClipPlan(1.0, 28.0, 7, "/x", "./c").n_windows == 4
    assert [(plan.window_start(k), plan.window_end(k)) for k in range(5)] == [
        (1, 7), (8, 14), (15, 21), (22, 28), (29, 30)]
    got = {k: np.asarray(idx).tolist() for k, idx in plan.windows_of(np.arange(6.0, 17.0))}
    assert got == {0: [0, 1], 1: [2, 3, 4, 5, 6, 7, 8], 2: [9, 10]}
    assert clips.plan("/o/crowd.usdc", 1, 30, 100, window=30) is None       # one window: no clips
    assert clips.window_frames(10) == clips.MAX_WINDOW and clips.window_frames(10**6) == clips.MIN_WINDOW
    # The writers share one budget: twice the processes, half the window.
    assert clips.window_frames(5000, 2) == clips.AGENT_FRAMES_HELD // 10000 == 2 * clips.window_frames(5000, 4)


def test_clipped_shot_holds_the_same_animation_at_every_time(shots):
    a, b = (Usd.Stage.Open(shots[k].shot) for k in ("inline", "clipped"))
    folder = clips.clips_folder(shots["clipped"].crowd)
    assert sorted(p.name for p in Path(folder).iterdir()) == [
        f"crowd.{k:04d}.usdc" for k in range(5)] + ["crowd.manifest.usdc"]
    assert not Path(clips.clips_folder(shots["inline"].crowd)).exists()
    # Sub-frame times across window boundaries interpolate as in one layer.
    times = [float(t) for t in range(1, 31)] + [7.5, 8.25, 14.5, 15.5, 28.75, 29.5]
    anims = [p for p in a.Traverse() if p.GetTypeName() == "SkelAnimation"]
    assert anims
    for prim in anims:
        other = b.GetPrimAtPath(prim.GetPath())
        for name in ("rotations", "translations"):
            x, y = prim.GetAttribute(name), other.GetAttribute(name)
            assert x.GetTimeSamples() == y.GetTimeSamples() == [float(t) for t in range(1, 31)]
            for t in times:
                assert np.array_equal(np.asarray(x.Get(t)), np.asarray(y.Get(t))), (prim.GetPath(), name, t)
        agent = prim.GetParent()
        for name in ("crowd:state:behavior", "crowd:state:animClass", "crowd:state:health"):
            x, y = agent.GetAttribute(name), other.GetParent().GetAttribute(name)
            assert [x.Get(t) for t in times] == [y.Get(t) for t in times], (agent.GetPath(), name)


def test_reading_a_clipped_shot_back_gives_the_same_crowd(shots):
    (fa, ia), (fb, ib) = (read_crowd(shots[k].shot) for k in ("inline", "clipped"))
    assert ia.path == ib.path
    for f in ("position", "heading", "behavior", "anim_class", "health"):
        assert np.array_equal(getattr(fa, f), getattr(fb, f)), f
    assert len(set(fb.behavior[:, 0].tolist())) > 1           # the tokens do change over the shot


def test_plain_usd_core_reads_the_clipped_shot(shots):
    # No usdcrowd import, no schema registration: a fresh interpreter with usd-core only.
    code = """if True:
        import json, sys
        from pxr import Usd
        s = Usd.Stage.Open(sys.argv[1])
        out = {}
        for p in s.Traverse():
            if p.GetTypeName() == "SkelAnimation":
                out[str(p.GetPath())] = [list(map(float, p.GetAttribute("translations").Get(t)[0])) for t in (3, 8, 8.5, 30)]
        print(json.dumps(out))
    """
    got = {}
    for k in ("inline", "clipped"):
        run = subprocess.run([sys.executable, "-c", code, shots[k].shot], capture_output=True, text=True, check=True)
        got[k] = json.loads(run.stdout)
    assert got["inline"] and got["inline"] == got["clipped"]


@pytest.mark.parametrize("workers", [1, 2])
def test_part_writers_split_their_layers_over_time(museum_path, tmp_path, monkeypatch, workers):
    monkeypatch.setattr(crowd_layer, "AGENTS_PER_PART", 4)
    sc = load_scenario(museum_path)
    frames = straight_walk(sc.agents, sc.time)
    out = tmp_path / "crowd.usdc"
    writer = crowd_layer.CrowdLayerWriter(out, sc, StageFrame(), "World", workers=workers, clip_frames=WINDOW)
    for chunk in _chunks(frames, 5):
        writer.write_chunk(chunk)
    writer.save()
    stage = Usd.Stage.Open(str(out))
    stems = [p.stem for p in tmp_path.glob("crowd.part*.usdc")] if workers > 1 else ["crowd"]
    files = {p.name for p in (tmp_path / "crowd.clips").iterdir()}
    n_win = clips.ClipPlan(sc.time.start, sc.time.end, WINDOW, "", "").n_windows
    assert files == {f"{s}.{k:04d}.usdc" for s in stems for k in range(n_win)} | {f"{s}.manifest.usdc" for s in stems}
    for i, path in enumerate(sc.agents.path):
        attr = stage.GetAttributeAtPath(f"{path}/Anim.translations")
        assert attr.GetTimeSamples() == list(frames.times)
        # The root joint's translation is the walked position (straight_walk has no stage transform).
        root = np.array([attr.Get(float(t))[0] for t in frames.times])
        assert np.allclose(root[:, :2], frames.position[:, i, :2], atol=1e-5), path
    assert not list(tmp_path.glob(".crowd.clips.partial-*"))


def test_a_failed_run_leaves_no_clips(museum_path, tmp_path):
    def failing(sc):
        frames = straight_walk(sc.agents, sc.time)
        chunks = _chunks(frames, 5)
        yield next(chunks)
        yield next(chunks)      # a window has been saved by now
        raise RuntimeError("the source broke")

    with pytest.raises(RuntimeError, match="broke"):
        author_shot(museum_path, tmp_path / "shot", failing, frames=FRAMES, progress=False, events=False,
                    clip_frames=WINDOW)
    assert sorted(p.name for p in (tmp_path / "shot").iterdir()) == []


def test_an_interrupted_runs_clip_folder_is_removed_by_the_next_run(tmp_path):
    left = tmp_path / ".crowd.clips.partial-0123abcd"
    left.mkdir()
    (left / "crowd.0000.usdc").write_bytes(b"PXR-USDC")
    keep = tmp_path / "crowd.clips"
    keep.mkdir()
    output_dir(tmp_path)
    assert not left.exists() and keep.exists()


def test_rerun_in_one_layer_removes_the_previous_clips(shots, museum_path):
    folder = clips.clips_folder(shots["clipped"].crowd)
    out = Path(shots["clipped"].shot).parent
    author_shot(museum_path, out, _wandering, frames=(1, 5), progress=False, events=False, clip_frames=WINDOW)
    assert not Path(folder).exists()
    assert [p for p in validate(out / "shot.usda") if p.severity == "error"] == []


def test_missing_or_truncated_clips_are_one_line_errors(shots):
    folder = Path(clips.clips_folder(shots["clipped"].crowd))
    clip = folder / "crowd.0002.usdc"
    data = clip.read_bytes()
    clip.write_bytes(data[:len(data) // 3])
    with pytest.raises(StageError, match=r"crowd\.0002\.usdc, which is truncated or damaged") as err:
        open_stage(shots["clipped"].shot)
    assert err.value.file.endswith("crowd.usdc") and "\n" not in str(err.value)
    clip.unlink()
    with pytest.raises(StageError, match=r"crowd\.0002\.usdc, which does not exist"):
        read_crowd(shots["clipped"].shot)


def test_validate_finds_non_finite_samples_inside_a_clip(shots):
    folder = Path(clips.clips_folder(shots["clipped"].crowd))
    layer = Sdf.Layer.FindOrOpen(str(folder / "crowd.0003.usdc"))
    anim = next(p for p in load_scenario_paths(shots["clipped"].shot))
    path = Sdf.Path(f"{anim}/Anim.translations")
    value = np.array(layer.QueryTimeSample(path, 24.0))
    value[1, 2] = np.nan
    layer.SetTimeSample(path, 24.0, Vt.Vec3fArray.FromNumpy(value.astype(np.float32)))
    layer.Save()
    found = [p for p in validate(shots["clipped"].shot) if p.severity == "error"]
    assert [(p.prim, p.attribute) for p in found] == [(f"{anim}/Anim", "translations")]
    assert "time 24" in found[0].message


def load_scenario_paths(shot):
    """Agent prim paths of a shot."""
    return read_crowd(shot, frames=(1, 1))[1].path
