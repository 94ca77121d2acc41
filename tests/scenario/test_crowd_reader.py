"""A shot's crowd layer read back into CrowdFrames (usdcrowd.scenario.crowd.read_crowd)."""

from __future__ import annotations

import numpy as np
import pytest

from usdcrowd.core import model
from usdcrowd.core.resources import data_dir

# Enough frames for class changes, blends between them and several simulation chunks.
FRAMES = (1, 120)


def _wrap(a):
    return np.mod(a + np.pi, 2.0 * np.pi) - np.pi


@pytest.fixture(scope="module")
def museum(tmp_path_factory):
    """The museum simulated and authored as a shot; the simulated frames kept; the shot read back."""
    from usdcrowd.jobs.pipeline import author_shot
    from usdcrowd.scenario.crowd import read_crowd
    from usdcrowd.sim import simulate_chunks
    from usdcrowd.sim.simulation import concat_frames

    kept, scenario = [], []

    def source(sc):
        scenario.append(sc)
        for chunk in simulate_chunks(sc):
            kept.append(chunk)
            yield chunk

    out = tmp_path_factory.mktemp("crowd_reader")
    shot = author_shot(data_dir("stages") / "museum.usda", out, source, frames=FRAMES, progress=False).shot
    frames, info = read_crowd(shot)
    return shot, scenario[0], concat_frames(kept), frames, info


def _rows(info, scenario):
    """Rows of the read frames in the scenario's agent order."""
    assert sorted(info.path) == sorted(scenario.agents.path)
    return [info.path.index(p) for p in scenario.agents.path]


def test_read_crowd_gives_back_the_simulated_state(museum):
    _, sc, sim, fr, info = museum
    rows = _rows(info, sc)
    assert fr.position.shape == sim.position.shape and fr.position.dtype == np.float32
    np.testing.assert_array_equal(fr.times, sim.times)
    # The recovery has to see through blends between animation classes: the run must have some.
    assert (np.diff(sim.anim_class.astype(int), axis=0) != 0).sum() >= 5
    np.testing.assert_allclose(fr.position[:, rows], sim.position, rtol=0, atol=1e-4)
    err = np.abs(_wrap(fr.heading[:, rows].astype(np.float64) - sim.heading)).max()
    assert err < 1e-4, f"heading off by {err:.3g} rad"
    for name in ("behavior", "anim_class", "health"):
        np.testing.assert_array_equal(getattr(fr, name)[:, rows], getattr(sim, name), err_msg=name)
    np.testing.assert_array_equal(fr.path_method[rows], sim.path_method)
    assert np.all(fr.anim_phase == 0) and np.all(np.isnan(fr.look_at))


def test_velocity_is_the_backward_difference_of_positions(museum):
    _, sc, sim, fr, info = museum
    rows = _rows(info, sc)
    v = fr.velocity[:, rows]
    diff = np.diff(sim.position[..., :2].astype(np.float64), axis=0) * sc.time.fps
    np.testing.assert_allclose(v[1:], diff, atol=1e-3)
    np.testing.assert_allclose(v[0], diff[0], atol=1e-3)        # the shot's first frame: forward difference
    # Close to the simulation's own velocity, which constraints and substeps make differ slightly.
    assert np.median(np.abs(v - sim.velocity)) < 0.02


def test_info_describes_the_rows(museum):
    _, sc, _, fr, info = museum
    rows = _rows(info, sc)
    np.testing.assert_array_equal(info.agent_id[rows], sc.agents.agent_id)
    np.testing.assert_array_equal(info.visible[rows], sc.agents.visible)
    assert not info.visible.all()                                       # the museum's invisible leader
    assert [info.group[r] for r in rows] == [sc.groups.path[g] for g in sc.agents.group]
    np.testing.assert_allclose(info.height[rows], sc.agents.height, rtol=1e-6)
    assert info.time == model.TimeRange(*map(float, FRAMES), sc.time.fps) == info.shot_time
    assert info.rows[info.path[3]] == 3


def test_a_window_of_frames_matches_the_whole_read(museum):
    from usdcrowd.scenario.crowd import read_crowd

    shot, _, _, whole, _ = museum
    part, info = read_crowd(shot, frames=(40, 75))
    k = slice(39, 75)
    assert info.time.start == 40 and info.time.end == 75 and len(part.times) == 36
    for name in ("position", "heading", "velocity", "behavior", "anim_class", "health"):
        np.testing.assert_allclose(getattr(part, name), getattr(whole, name)[k], atol=1e-6, err_msg=name)
    with pytest.raises(ValueError, match="not within"):
        read_crowd(shot, frames=(0, 10))


@pytest.mark.parametrize("size", [5, 17])
def test_reading_in_windows_gives_the_whole_read(museum, size):
    """Windows whose starts fall inside blends, read with a bounded look-back, join into the whole read."""
    from usdcrowd.character.animation import BLEND_FRAMES
    from usdcrowd.character.root import frames_since_change
    from usdcrowd.scenario.crowd import read_crowd

    shot, _, _, whole, _ = museum
    starts = list(range(FRAMES[0], FRAMES[1] + 1, size))
    since = frames_since_change(whole.anim_class)
    # Some window starts with an agent in the middle of a class change: the look-back must reach its key pose.
    assert any((since[s - FRAMES[0]] < BLEND_FRAMES - 1).any() for s in starts[1:])
    parts = [read_crowd(shot, frames=(s, min(s + size - 1, FRAMES[1])))[0] for s in starts]
    for name in ("position", "heading", "velocity", "behavior", "anim_class", "health"):
        joined = np.concatenate([getattr(p, name) for p in parts])
        np.testing.assert_allclose(joined, getattr(whole, name), atol=1e-6, err_msg=name)


def test_samples_follow_the_composed_value_over_the_crowd_layer(museum):
    """A stronger opinion (here a default in the session layer) wins over the crowd layer's samples."""
    from pxr import Gf, Usd, Vt

    from usdcrowd.scenario.crowd import _samples

    shot, *_, info = museum
    stage = Usd.Stage.Open(str(shot))
    attr = stage.GetPrimAtPath(info.path[0] + "/Anim").GetAttribute("translations")
    times = [1.0, 2.0, 3.0]
    before = _samples(attr, times, np.float32, (3, 3))
    np.testing.assert_array_equal(before[1], np.array(attr.Get(2.0)))
    with Usd.EditContext(stage, stage.GetSessionLayer()):
        attr.Set(Vt.Vec3fArray([Gf.Vec3f(1, 2, 3), Gf.Vec3f(0, 0, 0.1), Gf.Vec3f(0, 0, 0.45)]))
    after = _samples(attr, times, np.float32, (3, 3))
    np.testing.assert_array_equal(after[:, 0], np.broadcast_to([1.0, 2.0, 3.0], (3, 3)))


def test_y_up_centimetre_shot_reads_in_canonical_metres(write_stage, tmp_path):
    from tests.helpers.frames import straight_walk

    from usdcrowd.jobs.pipeline import author_shot
    from usdcrowd.scenario.crowd import read_crowd

    scenario = write_stage('''
    def Xform "World"
    {
        def CrowdGroup "Walkers"
        {
            uniform int crowd:clones = 6
            uniform float crowd:spawnRadius = 400
        }
    }
    ''', up="Y", mpu=0.01, end=30)
    made = []

    def source(sc):
        made.append(straight_walk(sc.agents, sc.time))
        return made

    shot = author_shot(scenario, tmp_path / "shot", source, progress=False).shot
    fr, info = read_crowd(shot)
    sim = made[0]
    assert len(info) == 6
    np.testing.assert_allclose(fr.position, sim.position, atol=1e-4)     # same row order: one group
    err = np.abs(_wrap(fr.heading.astype(np.float64) - sim.heading)).max()
    assert err < 1e-4, f"heading off by {err:.3g} rad"
    assert np.abs(fr.position[..., :2]).max() > 1.0                       # metres, not centimetres


def test_read_crowd_refuses_a_stage_without_animated_agents():
    from usdcrowd.core.errors import StageError
    from usdcrowd.scenario.crowd import read_crowd

    with pytest.raises(StageError, match="no animated agent"):
        read_crowd(data_dir("stages") / "museum.usda")


def test_recover_root_motion_inverts_the_animation_through_blends_and_chunks():
    """No USD: animate simulated frames chunk by chunk as the crowd layer does, then invert."""
    from tests.helpers.scenarios import crossing

    from usdcrowd.character.animation import Animator
    from usdcrowd.character.root import (apply_root_motion, blend_weight, frames_since_change,
                                         recover_root_motion)
    from usdcrowd.sim import SimSettings, simulate_chunks
    from usdcrowd.sim.simulation import concat_frames

    sc = crossing(n_per_side=10, frames=96)
    chunks = list(simulate_chunks(sc, SimSettings(chunk_frames=30)))
    fr = concat_frames(chunks)
    animator = Animator(1.0 / sc.time.fps, sc.agents.height)
    rot, trans = [], []
    for ch in chunks:
        r, t = animator(ch)
        r, t, scale = apply_root_motion(r, t, ch.position, ch.heading, sc.agents.height)
        rot.append(r)
        trans.append(t)
    rot, trans = np.concatenate(rot), np.concatenate(trans)
    since = frames_since_change(fr.anim_class)
    blends = blend_weight(since) < 1
    assert blends.sum() > 10
    pos, heading = recover_root_motion(rot[..., 0, :], trans[..., 0, :], rot[..., 1, :], scale, fr.anim_class,
                                       since)
    np.testing.assert_allclose(pos, fr.position, atol=1e-5)
    err = np.abs(_wrap(heading - fr.heading))
    assert err[blends].max() < 1e-5 and err.max() < 1e-5, (err[blends].max(), err.max())
