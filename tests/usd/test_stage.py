"""The shot stage as another USD reader sees it: layers, skinning, round trip, units."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom, UsdSkel

from usdcrowd.character import animation, body, rig
from usdcrowd.character.root import apply_root_motion
from usdcrowd.jobs.pipeline import author_shot
from usdcrowd.scenario import load_scenario
from usdcrowd.core.tolerances import ROUND_TRIP_ATOL, SKINNING_ATOL
from usdcrowd.jobs.validation import validate

from tests.helpers.frames import straight_walk
from tests.helpers.shots import Y_UP_CM


def _walk(sc):
    yield straight_walk(sc.agents, sc.time)


@pytest.fixture
def museum_shot(tmp_path, museum_path):
    """The museum scenario with every agent walking straight, authored as a shot."""
    result = author_shot(museum_path, tmp_path / "shot", _walk, frames=(1, 24), progress=False)
    return result, load_scenario(museum_path)


def _skinned(stage, agent_path, time):
    """Points of an agent's body skinned by UsdSkel itself, in world space."""
    cache = UsdSkel.Cache()
    root = UsdSkel.Root(stage.GetPrimAtPath(agent_path))
    cache.Populate(root, Usd.TraverseInstanceProxies())
    (binding,) = cache.ComputeSkelBindings(root, Usd.TraverseInstanceProxies())
    skel_query = cache.GetSkelQuery(binding.GetSkeleton())
    (target,) = binding.GetSkinningTargets()
    xforms = skel_query.ComputeSkinningTransforms(time)
    points = target.GetPrim().GetAttribute("points").Get(time)
    assert target.ComputeSkinnedPoints(xforms, points, time)
    world = np.array(UsdGeom.Xformable(binding.GetSkeleton().GetPrim()).ComputeLocalToWorldTransform(time))
    p = np.hstack([np.array(points, dtype=np.float64), np.ones((len(points), 1))])
    return (p @ world)[:, :3]


def test_shot_sublayers_generated_layers_over_the_untouched_scenario(museum_shot, museum_path):
    result, _ = museum_shot
    before = museum_path.read_bytes()
    layer = Sdf.Layer.FindOrOpen(result.shot)
    assert [p.split("/")[-1] for p in layer.subLayerPaths] == ["cameras.usda", "crowd.usdc", "museum.usda"]
    assert museum_path.read_bytes() == before
    stage = Usd.Stage.Open(result.shot)
    assert UsdGeom.GetStageUpAxis(stage) == "Z" and stage.GetStartTimeCode() == 1 and stage.GetEndTimeCode() == 24


def _world_pose(sc):
    """What usdcrowd authors for the straight walk: frames and world joint rotations, translations, scales."""
    frames = straight_walk(sc.agents, sc.time)
    rot, trans = animation.animate(frames, 1 / 24, sc.agents.height)
    return (frames, *apply_root_motion(rot, trans, frames.position, frames.heading, sc.agents.height))


def test_characters_skin_in_usdskel_as_usdcrowd_computes_them(museum_shot):
    result, sc = museum_shot
    stage = Usd.Stage.Open(result.shot)
    frames, rot_w, trans_w, scale = _world_pose(sc)
    b = body.build_body()
    for i in (1, 6, 18):
        for t in (1, 12, 24):
            k = t - 1
            local = rig.compose_local(rot_w[k, i], trans_w[k, i])
            local[0, :3, :3] *= scale[i]        # uniform scale of the root joint
            ours = rig.skin_points(b.points, b.joint_indices, b.joint_weights,
                                   rig.skinning_transforms(rig.local_to_skel(local)))
            theirs = _skinned(stage, sc.agents.path[i], t)
            assert np.abs(ours - theirs).max() < SKINNING_ATOL
            # The body stands where the simulation put it, feet on the ground.
            assert np.allclose(theirs[:, :2].mean(0), frames.position[k, i, :2], atol=0.25)
            assert theirs[:, 2].min() == pytest.approx(0.0, abs=0.06)
            assert theirs[:, 2].max() == pytest.approx(sc.agents.height[i], rel=0.05)


def test_round_trip_time_samples_and_resolved_table(museum_shot):
    result, sc = museum_shot
    stage = Usd.Stage.Open(result.shot)
    _, rot_w, trans_w, _ = _world_pose(sc)
    for i in (0, 7):
        anim = UsdSkel.Animation(stage.GetPrimAtPath(f"{sc.agents.path[i]}/Anim"))
        for t in (1, 5, 24):
            q = np.array([[x.GetReal(), *x.GetImaginary()] for x in anim.GetRotationsAttr().Get(t)])
            assert np.allclose(q, rot_w[t - 1, i], atol=ROUND_TRIP_ATOL)
            assert np.allclose(np.array(anim.GetTranslationsAttr().Get(t)), trans_w[t - 1, i], atol=1e-4)
    again = load_scenario(result.shot)
    assert again.agents.path == sc.agents.path
    for name in ("agent_id", "leader", "personality", "behavior", "color", "speed", "height", "start"):
        assert np.allclose(getattr(again.agents, name), getattr(sc.agents, name), atol=1e-5), name


def test_state_tokens_and_visibility(museum_shot):
    result, sc = museum_shot
    stage = Usd.Stage.Open(result.shot)
    guide = stage.GetPrimAtPath("/World/Crowd/Visitors/Family/Guide")
    assert UsdGeom.Imageable(guide).ComputeVisibility(1) == UsdGeom.Tokens.invisible
    clone = stage.GetPrimAtPath(sc.agents.path[1])
    assert clone.GetAttribute("crowd:state:animClass").Get(10) == "walk"
    assert clone.GetAttribute("crowd:agentId").Get() == sc.agents.agent_id[1]


def test_every_generated_stage_validates_with_no_errors(museum_shot):
    result, _ = museum_shot
    for path in (result.shot, result.crowd, result.cameras):
        errors = [p for p in validate(path) if p.severity == "error"]
        assert errors == [], [str(e) for e in errors]


def test_y_up_centimetre_stage_is_read_in_metres_z_up(write_stage):
    sc = load_scenario(write_stage(Y_UP_CM, up="Y", mpu=0.01))
    walker = sc.agents.path.index("/World/Crowd/Walker")
    # Y-up (x, y, z) -> Z-up (x, -z, y), centimetres -> metres.
    assert np.allclose(sc.agents.start[walker], (3.0, 4.0, 0.0))
    clones = [i for i, p in enumerate(sc.agents.path) if "clone_" in p]
    d = np.linalg.norm(sc.agents.start[clones, :2] - np.array([1.0, 2.0]), axis=1)
    assert np.all(d <= 0.5 + 1e-9)
    (box,) = sc.obstacles.polygons
    assert np.allclose(box.min(0), (-0.5, -5.5)) and np.allclose(box.max(0), (0.5, -4.5))
    assert sc.obstacles.height[0] == pytest.approx(1.0)


def test_y_up_centimetre_shot_places_characters_in_stage_units(write_stage, tmp_path):
    path = write_stage(Y_UP_CM, up="Y", mpu=0.01)
    result = author_shot(path, tmp_path / "shot", _walk, progress=False)
    stage = Usd.Stage.Open(result.shot)
    assert UsdGeom.GetStageUpAxis(stage) == "Y" and UsdGeom.GetStageMetersPerUnit(stage) == pytest.approx(0.01)
    sc = load_scenario(path)
    i = sc.agents.path.index("/World/Crowd/Walker")
    pts = _skinned(stage, "/World/Crowd/Walker", 1)
    # Standing upright along +Y, in centimetres, at the authored start.
    assert pts[:, 1].min() == pytest.approx(0.0, abs=6) and pts[:, 1].max() == pytest.approx(100 * sc.agents.height[i], rel=0.05)
    assert np.allclose([pts[:, 0].mean(), pts[:, 2].mean()], [300, -400], atol=25)
    assert [p for p in validate(result.shot) if p.severity == "error"] == []


@pytest.mark.parametrize("agents", [30, 1600])    # 1600: written as parallel part layers
def test_same_seed_gives_the_same_bytes(tmp_path, agents):
    from usdcrowd.jobs.pipeline import simulate_shot
    from usdcrowd.jobs.templates import new_scenario

    scenario = tmp_path / "s.usda"
    new_scenario("museum", scenario, agents=agents, seed=5)
    runs = [simulate_shot(scenario, tmp_path / f"run{k}", frames=(1, 6), progress=False) for k in range(2)]
    files = sorted(p.name for p in (tmp_path / "run0").iterdir() if p.suffix in (".usda", ".usdc"))
    if agents >= 1600:
        assert any(".part" in f for f in files)
    for name in files:
        assert (tmp_path / "run0" / name).read_bytes() == (tmp_path / "run1" / name).read_bytes(), name
    other = simulate_shot(scenario, tmp_path / "other", seed=6, frames=(1, 6), progress=False)
    assert Path(other.crowd).read_bytes() != Path(runs[0].crowd).read_bytes()


PLACED = '''
def Xform "World"
{
    double3 xformOp:translate = (100, 0, 0)
    uniform token[] xformOpOrder = ["xformOp:translate"]
    def CrowdGroup "Pair"
    {
        uniform token crowd:behavior = "rest"
        def SkelRoot "B" (prepend apiSchemas = ["CrowdAgentAPI"])
        {
            double3 xformOp:translate = (0.75, 2, 0)
            float xformOp:rotateZ = 180
            uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateZ"]
        }
    }
}
'''


def test_agents_stand_where_simulated_whatever_their_authored_transforms(write_stage, tmp_path):
    # The scenario's placement says where B starts (world 100.75, 2) facing -X;
    # the shot must not apply it a second time on top of the root motion.
    path = write_stage(PLACED)
    sc = load_scenario(path)
    assert np.allclose(sc.agents.start[0], (100.75, 2, 0)) and np.isclose(abs(sc.agents.start_heading[0]), np.pi)
    result = author_shot(path, tmp_path / "shot", _walk, frames=(1, 2), progress=False)
    pts = _skinned(Usd.Stage.Open(result.shot), "/World/Pair/B", 1)
    assert np.allclose(pts[:, :2].mean(0), (100.75, 2), atol=0.15)
    # The feet point forward: facing -X puts them on the -X side of the body.
    feet = pts[pts[:, 2] < 0.08]
    assert feet[:, 0].mean() < pts[:, 0].mean() - 0.03


def test_a_dead_part_writer_is_an_error_not_a_hang(museum_path, tmp_path):
    from usdcrowd.scenario import StageFrame
    from usdcrowd.usd.crowd_layer import CrowdLayerWriter

    sc = load_scenario(museum_path)
    writer = CrowdLayerWriter(tmp_path / "crowd.usdc", sc, StageFrame(), "World", workers=2)
    writer._workers[0][0].kill()
    frames = straight_walk(sc.agents, sc.time)
    with pytest.raises(RuntimeError, match="died"):
        # Far more than a pipe's buffer: sending must fail, not block.
        for _ in range(200):
            writer.write_chunk(frames)
        writer.save()
    assert not (tmp_path / "crowd.usdc").exists()
    assert not list(tmp_path.glob("crowd.part*"))


def test_part_layers_hold_the_same_samples_as_one_layer(museum_path, tmp_path, monkeypatch):
    from usdcrowd.scenario import StageFrame
    from usdcrowd.usd import crowd_layer

    sc = load_scenario(museum_path)
    frames = straight_walk(sc.agents, sc.time)
    monkeypatch.setattr(crowd_layer, "AGENTS_PER_PART", 4)
    saved = {}
    for workers in (1, 2):
        out = tmp_path / f"w{workers}" / "crowd.usdc"
        out.parent.mkdir()
        writer = crowd_layer.CrowdLayerWriter(out, sc, StageFrame(), "World", workers=workers)
        writer.write_chunk(frames)
        saved[workers] = Sdf.Layer.FindOrOpen(writer.save())
    n = len(sc.agents)
    assert len(saved[2].subLayerPaths) == 2 * round(n / 2 / 4) > 2
    stages = {w: Usd.Stage.Open(layer) for w, layer in saved.items()}
    for path in sc.agents.path:
        for attr in ("rotations", "translations"):
            a, b = (stages[w].GetAttributeAtPath(f"{path}/Anim.{attr}") for w in (1, 2))
            assert a.GetTimeSamples() == b.GetTimeSamples() and len(a.GetTimeSamples()) == len(frames.times)
            for t in a.GetTimeSamples()[::7]:
                assert np.array_equal(np.asarray(a.Get(t)), np.asarray(b.Get(t))), (path, attr, t)
        ext = [stages[w].GetPrimAtPath(path).GetAttribute("extent").Get() for w in (1, 2)]
        assert np.array_equal(np.asarray(ext[0]), np.asarray(ext[1]))


def test_plain_usd_core_sees_groups_as_transforms_in_shots_and_new_scenarios(write_stage, tmp_path):
    """fallbackPrimTypes in the root layers: a reader without our schemas gets Xform groups, Scope events."""
    import json
    import subprocess
    import sys

    from usdcrowd.jobs.templates import new_scenario

    shot = author_shot(write_stage(Y_UP_CM, up="Y", mpu=0.01), tmp_path / "shot", _walk, progress=False).shot
    scenario = tmp_path / "museum.usda"
    new_scenario("museum", scenario, agents=8)
    code = """if True:
        import json, sys
        from pxr import Usd, UsdGeom
        out = {}
        for path, prim in ((sys.argv[1], "/World/Crowd"), (sys.argv[2], "/World/Crowd/Visitors")):
            stage = Usd.Stage.Open(path)
            p = stage.GetPrimAtPath(prim)
            out[prim] = [p.GetTypeName(), p.IsA(UsdGeom.Xform), p.GetPrimTypeInfo().GetSchemaTypeName()]
        print(json.dumps(out))
    """
    run = subprocess.run([sys.executable, "-c", code, shot, str(scenario)], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr[-1500:]
    got = json.loads(run.stdout)
    # The authored type stays CrowdGroup; the type that applies without our plugin is Xform.
    assert got == {"/World/Crowd": ["CrowdGroup", True, "Xform"],
                   "/World/Crowd/Visitors": ["CrowdGroup", True, "Xform"]}
