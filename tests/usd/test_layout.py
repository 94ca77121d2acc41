"""A shot lives in its parent's space: moved, rotated, scaled, animated or referenced into a set,
its crowd, cameras, events and scenery stay together, for plain usd-core and for usdcrowd's readers."""

from __future__ import annotations

import json
import math
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from tests.helpers.shots import cli_museum_shot
from usdcrowd.character.body import REGIONS

# A layer over the shot: /World translated by 5 m, turned 30 degrees about Z and scaled by 2.
MOVE = np.array([[math.cos(math.radians(30)) * 2, math.sin(math.radians(30)) * 2, 0, 0],
                 [-math.sin(math.radians(30)) * 2, math.cos(math.radians(30)) * 2, 0, 0],
                 [0, 0, 2, 0],
                 [5, -3, 0.5, 1]], dtype=np.float64)


@pytest.fixture(scope="module")
def museum_shot(tmp_path_factory):
    """A museum shot of 6 agents and 24 frames made by the command line: (scenario, shot folder)."""
    return cli_museum_shot(tmp_path_factory.mktemp("layout"), agents=6, last_frame=24)


def _over_world(folder: Path, shot: Path, ops: str, name: str) -> Path:
    """A stage that sublayers the shot and moves /World with ``ops`` (usda lines)."""
    path = folder / name
    from usdcrowd.schema import FALLBACK_PRIM_TYPES

    body = textwrap.indent(textwrap.dedent(ops).strip(), "    ")
    # What `validate` asks of a stage over a shot: the fallbacks tools without our schemas need.
    fallbacks = "".join(f"        token[] {k} = {json.dumps(v)}\n" for k, v in FALLBACK_PRIM_TYPES.items())
    path.write_text(f'#usda 1.0\n(\n    defaultPrim = "World"\n    fallbackPrimTypes = {{\n{fallbacks}    }}\n'
                    f'    metersPerUnit = 1\n    upAxis = "Z"\n    subLayers = [@{shot.as_posix()}@]\n)\n'
                    f'over "World"\n{{\n{body}\n}}\n')
    return path


@pytest.fixture(scope="module")
def moved_shot(museum_shot, tmp_path_factory):
    """The museum shot under a layer that moves, turns and scales /World by MOVE."""
    _, shot = museum_shot
    return _over_world(tmp_path_factory.mktemp("moved"), shot / "shot.usda", '''
        matrix4d xformOp:transform:layout = ( (1.7320508075688772, 1, 0, 0), (-1, 1.7320508075688772, 0, 0), (0, 0, 2, 0), (5, -3, 0.5, 1) )
        uniform token[] xformOpOrder = ["xformOp:transform:layout"]
        ''', "moved.usda")


PLAIN_USD = textwrap.dedent('''
    import json, sys
    from pxr import Usd, UsdGeom, UsdSkel
    out = {}
    for path in sys.argv[1:]:
        stage = Usd.Stage.Open(path)
        t = 12.0
        cache = UsdGeom.XformCache(Usd.TimeCode(t))
        rows = {}
        for prim in stage.Traverse():
            if prim.IsA(UsdSkel.Root) or prim.IsA(UsdGeom.Camera):
                rows[str(prim.GetPath())] = [list(r) for r in cache.GetLocalToWorldTransform(prim)]
            if prim.IsA(UsdGeom.Xformable):
                ops = UsdGeom.Xformable(prim).GetXformOpOrderAttr().Get() or []
                if "!resetXformStack!" in list(ops):
                    rows.setdefault("reset", []).append(str(prim.GetPath()))
        out[path] = rows
    print(json.dumps(out))
    ''')


def _plain_usd(*stages) -> dict:
    """World transforms of every SkelRoot and camera at frame 12, read by usd-core alone (no usdcrowd)."""
    r = subprocess.run([sys.executable, "-c", PLAIN_USD, *map(str, stages)], capture_output=True, text=True,
                       check=True, cwd="/")
    return json.loads(r.stdout)


def test_no_agent_or_generated_camera_resets_the_transform_stack(museum_shot):
    _, shot = museum_shot
    rows = _plain_usd(shot / "shot.usda")[str(shot / "shot.usda")]
    assert "reset" not in rows, rows.get("reset")
    assert sum(1 for p in rows if "/Crowd" in p or p.count("/") > 2) >= 6


def test_plain_usd_moves_agents_and_cameras_with_their_parent(museum_shot, moved_shot):
    _, shot = museum_shot
    got = _plain_usd(shot / "shot.usda", moved_shot)
    before, after = got[str(shot / "shot.usda")], got[str(moved_shot)]
    assert before.keys() == after.keys()
    for path in before:
        np.testing.assert_allclose(np.array(after[path]), np.array(before[path]) @ MOVE, atol=1e-6,
                                   err_msg=path)


def test_usdcrowd_readers_see_the_moved_shot_where_usd_puts_it(museum_shot, moved_shot):
    from usdcrowd.scenario.shot_scene import ShotScene
    from usdcrowd.scenario.crowd import read_crowd

    _, shot = museum_shot
    a, b = ShotScene(shot / "shot.usda"), ShotScene(moved_shot)
    assert a.agent_paths == b.agent_paths and a.camera_paths == b.camera_paths
    for t in (1.0, 12.0, 24.0):
        ja, jb = a.agents(t).joints_world, b.agents(t).joints_world
        np.testing.assert_allclose(jb, ja @ MOVE, atol=1e-4)
        for cam in a.camera_paths:
            ca, cb = a.camera(cam, t), b.camera(cam, t)
            np.testing.assert_allclose(cb.position, ca.position @ MOVE[:3, :3] + MOVE[3, :3], atol=1e-4)
            # The whole scene moved with the camera: every joint lands on the same pixel.
            heads_a = ja[:, :, 3, :3].reshape(-1, 3)
            heads_b = jb[:, :, 3, :3].reshape(-1, 3)
            pa, _ = ca.project(heads_a, 640, 360)
            pb, _ = cb.project(heads_b, 640, 360)
            np.testing.assert_allclose(pb, pa, atol=0.01)
    fa, _ = read_crowd(shot / "shot.usda")
    fb, _ = read_crowd(moved_shot)
    np.testing.assert_allclose(fb.position, fa.position @ MOVE[:3, :3] + MOVE[3, :3], atol=1e-4)
    np.testing.assert_allclose(np.angle(np.exp(1j * (fb.heading - fa.heading - math.radians(30)))), 0, atol=1e-4)


def test_an_animated_parent_carries_the_crowd_frame_by_frame(museum_shot, tmp_path):
    from usdcrowd.scenario.shot_scene import ShotScene
    from usdcrowd.scenario.crowd import read_crowd

    _, shot = museum_shot
    moving = _over_world(tmp_path, shot / "shot.usda", '''
        double3 xformOp:translate.timeSamples = { 1: (0, 0, 0), 24: (23, 0, 0) }
        uniform token[] xformOpOrder = ["xformOp:translate"]
        ''', "slide.usda")
    fa, _ = read_crowd(shot / "shot.usda")
    fb, _ = read_crowd(moving)
    shift = fa.times - 1.0                   # one metre a frame
    np.testing.assert_allclose(fb.position[..., 0], fa.position[..., 0] + shift[:, None], atol=1e-4)
    a, b = ShotScene(shot / "shot.usda"), ShotScene(moving)
    np.testing.assert_allclose(b.agents(13.0).joints_world[..., 3, 0], a.agents(13.0).joints_world[..., 3, 0] + 12, atol=1e-4)


Y_UP_SET = '''#usda 1.0
(
    defaultPrim = "Set"
    metersPerUnit = 0.01
    upAxis = "Y"
)
def Xform "Set"
{{
    def Xform "ShotA" (
        prepend references = @{shot}@
    )
    {{
        double3 xformOp:translate = (250, 0, -400)
        float xformOp:rotateX = -90
        float3 xformOp:scale = (100, 100, 100)
        uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateX", "xformOp:scale"]
    }}
}}
'''


def test_a_shot_referenced_into_a_y_up_centimetre_set_keeps_its_crowd_upright_and_life_size(museum_shot, tmp_path):
    """The usual corrective transform (Z-up metres into Y-up centimetres) puts crowd and cameras where the
    set's own geometry is, in usd-core and in usdcrowd's readers (canonical metres, Z up)."""
    from usdcrowd.scenario.shot_scene import ShotScene

    _, shot = museum_shot
    set_path = tmp_path / "set.usda"
    set_path.write_text(Y_UP_SET.format(shot=(shot / "shot.usda").as_posix()))
    a, b = ShotScene(shot / "shot.usda"), ShotScene(set_path)
    assert [p.replace("/World/", "/Set/ShotA/") for p in a.agent_paths] == b.agent_paths
    # Y-up centimetres back to canonical: the set's (250, 0, -400) cm is (2.5, 4, 0) m, Z up.
    offset = np.array([2.5, 4.0, 0.0])
    for t in (1.0, 24.0):
        np.testing.assert_allclose(b.agents(t).joints_world[..., 3, :3], a.agents(t).joints_world[..., 3, :3] + offset, atol=1e-4)
        for cam_a, cam_b in zip(a.camera_paths, b.camera_paths):
            np.testing.assert_allclose(b.camera(cam_b, t).position, a.camera(cam_a, t).position + offset, atol=1e-4)
            np.testing.assert_allclose(b.camera(cam_b, t).cam_to_world[:3, :3], a.camera(cam_a, t).cam_to_world[:3, :3],
                                       atol=1e-6)


SET = '''#usda 1.0
(
    defaultPrim = "Set"
    metersPerUnit = 0.01
    upAxis = "Y"
)
def Xform "Set"
{
    def Cube "Kiosk"
    {
        double size = 200
    }
}
'''


@pytest.fixture(scope="module")
def placed_shot(museum_shot, tmp_path_factory):
    """The museum shot placed by `usdcrowd place` in a Y-up centimetre set, moved and turned: (path, at, deg)."""
    from usdcrowd.cli import main

    _, shot = museum_shot
    folder = tmp_path_factory.mktemp("placed")
    (folder / "set.usda").write_text(SET)
    out = folder / "placed.usda"
    assert main(["place", str(shot / "shot.usda"), "--into", str(folder / "set.usda"), "-o", str(out),
                 "--at", "500", "0", "-300", "--rotate", "40"]) == 0
    return out, (500.0, 0.0, -300.0), 40.0


def test_place_puts_crowd_and_cameras_where_the_set_says(museum_shot, placed_shot):
    from usdcrowd.scenario.shot_scene import ShotScene
    from usdcrowd.scenario import stage_frame
    from usdcrowd.usd.place import placement_matrix

    _, shot = museum_shot
    path, at, deg = placed_shot
    a, b = ShotScene(shot / "shot.usda"), ShotScene(path)
    # Shot canonical metres -> shot stage -> set stage (the placement) -> set canonical metres, computed apart.
    m = a.frame.from_canonical @ placement_matrix(stage_frame(a.stage), stage_frame(b.stage), at, deg) \
        @ b.frame.to_canonical
    np.testing.assert_allclose(m[:3, :3] @ m[:3, :3].T, np.eye(3), atol=1e-9)        # upright, life size
    assert b.agent_paths == [p.replace("/World/", "/Set/Shot/World/") for p in a.agent_paths]
    for t in (1.0, 24.0):
        np.testing.assert_allclose(b.agents(t).joints_world, a.agents(t).joints_world @ m, atol=1e-4)
        for ca, cb in zip(a.camera_paths, b.camera_paths):
            np.testing.assert_allclose(b.camera(cb, t).position, a.camera(ca, t).position @ m[:3, :3] + m[3, :3],
                                       atol=1e-4)
    # --at 500 0 -300 cm in the Y-up set is (5, 3, 0) m in canonical Z-up metres.
    np.testing.assert_allclose(m[3, :3], [5.0, 3.0, 0.0], atol=1e-9)


def test_a_placed_shot_keeps_its_materials_and_validates_clean(museum_shot, placed_shot, capsys):
    """Materials and prototypes live under the default prim: a referencing stage binds every body region,
    to the same roughness as the shot, and validate finds nothing (toric targets mapped too)."""
    from usdcrowd.cli import main
    from usdcrowd.scenario.shot_scene import ShotScene

    _, shot = museum_shot
    path, _, _ = placed_shot
    code = '''
import sys
from pxr import Usd, UsdShade
stage = Usd.Stage.Open(sys.argv[1])
bound = unbound = 0
for prim in stage.Traverse():
    if prim.GetTypeName() == "GeomSubset" and "/Body/" in str(prim.GetPath()):
        mat, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
        bound, unbound = bound + bool(mat), unbound + (not mat)
print(bound, unbound)
'''
    r = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True, text=True, check=True, cwd="/")
    bound, unbound = map(int, r.stdout.split())
    assert unbound == 0 and bound >= 5 * 6
    np.testing.assert_array_equal(ShotScene(path).body.roughness, ShotScene(shot / "shot.usda").body.roughness)
    capsys.readouterr()
    assert main(["validate", str(path)]) == 0
    assert "0 error(s), 0 warning(s)" in capsys.readouterr().out


def test_validate_warns_when_a_referencing_stage_lacks_blenders_fallbacks(museum_shot, tmp_path, capsys):
    from usdcrowd.cli import main

    _, shot = museum_shot
    bare = tmp_path / "bare.usda"
    bare.write_text(f'#usda 1.0\n(\n    defaultPrim = "Set"\n    metersPerUnit = 1\n    upAxis = "Z"\n)\n'
                    f'def Xform "Set"\n{{\n    def "Shot" (\n        prepend references = @{(shot / "shot.usda").as_posix()}@\n'
                    f'    )\n    {{\n    }}\n}}\n')
    capsys.readouterr()
    assert main(["validate", str(bare)]) == 0                  # a warning, not an error
    out = capsys.readouterr().out
    assert "warning" in out and "fallbackPrimTypes" in out and "CrowdGroup" in out


def test_cameras_and_metrics_on_a_moved_stage_work_on_its_shot(museum_shot, moved_shot, tmp_path, capsys):
    """`cameras` on a stage over the shot rewrites the shot's cameras.usda (authored in the shot's space, so
    the moved stage shows them moved with it); `metrics` measures the shot the stage uses."""
    from pxr import Usd, UsdGeom

    from usdcrowd.cli import main
    from usdcrowd.scenario.shot_scene import ShotScene

    _, shot = museum_shot
    before = (shot / "cameras.usda").stat().st_mtime_ns
    assert main(["cameras", str(moved_shot), "--count", "2", "--seed", "5", "--no-progress"]) == 0
    assert (shot / "cameras.usda").stat().st_mtime_ns != before
    a, b = Usd.Stage.Open(str(shot / "shot.usda")), Usd.Stage.Open(str(moved_shot))
    cams = [p.GetPath() for p in a.Traverse() if p.IsA(UsdGeom.Camera)]
    assert len(cams) >= 2
    for path in cams:
        ma = np.array(UsdGeom.Xformable(a.GetPrimAtPath(path)).ComputeLocalToWorldTransform(10))
        mb = np.array(UsdGeom.Xformable(b.GetPrimAtPath(path)).ComputeLocalToWorldTransform(10))
        np.testing.assert_allclose(mb, ma @ MOVE, atol=1e-6)
    assert main(["metrics", str(moved_shot), "-o", str(tmp_path / "metrics"), "--counts", "2", "--no-progress"]) == 0
    assert (tmp_path / "metrics" / "summary.csv").exists()
    # A toric camera framed from the moved stage lands in the shot's cameras.usda, in the shot's space.
    paths = ShotScene(shot / "shot.usda").agent_paths
    assert main(["frame", str(moved_shot), "--behavior", "direct-track", "--targets", paths[2], paths[3],
                 "--shot", "long", "--name", "Layout", "--no-progress"]) == 0
    got = _plain_usd(shot / "shot.usda", moved_shot)        # a fresh process: the files as written now
    ma, mb = (np.array(got[str(p)]["/World/Cameras/Layout"]) for p in (shot / "shot.usda", moved_shot))
    np.testing.assert_allclose(mb, ma @ MOVE, atol=1e-6)


def _edit_shot_as_a_user(shot: Path, agents: list[str]) -> None:
    """Opinions a layout artist puts in shot.usda: a camera raised 3 m, one character deactivated, another
    moved 2 m along x, the lamp dimmed, a prop added."""
    from pxr import Gf, Sdf, Usd, UsdGeom

    stage = Usd.Stage.Open(str(shot / "shot.usda"))
    stage.SetEditTarget(stage.GetRootLayer())
    cam = UsdGeom.Xformable(stage.GetPrimAtPath("/World/Cameras/CrowdCam"))
    up = cam.AddTranslateOp(opSuffix="layout")
    up.Set(Gf.Vec3d(0, 0, 3))
    cam.SetXformOpOrder([up] + [op for op in cam.GetOrderedXformOps() if op.GetOpName() != up.GetOpName()])
    stage.GetPrimAtPath(agents[1]).SetActive(False)
    moved = UsdGeom.Xformable(stage.GetPrimAtPath(agents[2]))
    step = moved.AddTranslateOp(opSuffix="layout")
    step.Set(Gf.Vec3d(2, 0, 0))
    moved.SetXformOpOrder([step] + [op for op in moved.GetOrderedXformOps() if op.GetOpName() != step.GetOpName()])
    stage.GetPrimAtPath("/World/Lights/Lamp").GetAttribute("inputs:intensity").Set(50.0)
    UsdGeom.Cube.Define(stage, "/World/Props/Crate").GetSizeAttr().Set(0.5)
    stage.GetRootLayer().Save()
    Sdf.Layer.Find(str(shot / "shot.usda")).Reload()


def test_your_edits_in_shot_usda_survive_simulate_and_cameras(tmp_path, capsys):
    """shot.usda is the user's layer: re-running simulate or cameras leaves it byte for byte, and every edit
    in it shows in the readers both renderers use and in the final renderer's ground truth."""
    from pxr import Sdf

    from usdcrowd.cli import main
    from usdcrowd.groundtruth.mot import read_mot
    from usdcrowd.scenario.shot_scene import ShotScene
    from usdcrowd.jobs.summary import agent_list
    from usdcrowd.usd.cameras import cameras_in

    scenario, shot = cli_museum_shot(tmp_path, agents=6, last_frame=24)
    original = ShotScene(shot / "shot.usda")
    agents = original.agent_paths
    ids = dict(zip(agents, original._agent_static[1].tolist()))
    _edit_shot_as_a_user(shot, agents)
    edited = (shot / "shot.usda").read_bytes()
    # A camera made by `frame` is the user's work too.
    assert main(["frame", str(shot / "shot.usda"), "--behavior", "orbit", "--targets", agents[3], agents[4],
                 "--shot", "long", "--name", "Mine", "--no-progress"]) == 0
    assert main(["simulate", str(scenario), "-o", str(shot), "--frames", "1:24", "--no-progress"]) == 0
    assert (shot / "shot.usda").read_bytes() == edited
    assert "kept    1 camera(s) made by frame (Mine)" in capsys.readouterr().out
    assert "/World/Cameras/Mine" in cameras_in(shot / "cameras.usda")
    listed = [a["path"] for a in agent_list(shot / "shot.usda")]
    assert agents[1] not in listed and len(listed) == len(agents) - 1     # deactivated: gone, not made again
    assert main(["cameras", str(shot / "shot.usda"), "--no-progress"]) == 0
    assert (shot / "shot.usda").read_bytes() == edited

    # The generated layers alone, to compare with.
    plain = tmp_path / "plain.usda"
    layer = Sdf.Layer.CreateNew(str(plain))
    layer.subLayerPaths = [str(shot / "cameras.usda"), str(shot / "crowd.usdc"), str(scenario)]
    layer.startTimeCode, layer.endTimeCode = 1, 24
    layer.pseudoRoot.SetInfo("upAxis", "Z")
    layer.pseudoRoot.SetInfo("metersPerUnit", 1.0)
    layer.Save()
    a, b = ShotScene(plain), ShotScene(shot / "shot.usda")
    assert agents[1] not in b.agent_paths and len(b.agent_paths) == len(agents) - 1
    ja, jb = a.agents(12.0), b.agents(12.0)
    row_a, row_b = a.agent_paths.index(agents[2]), b.agent_paths.index(agents[2])
    np.testing.assert_allclose(jb.joints_world[row_b, :, 3, :3] - ja.joints_world[row_a, :, 3, :3],
                               [[2.0, 0, 0]] * 3, atol=1e-5)
    np.testing.assert_allclose(b.camera("/World/Cameras/CrowdCam", 12.0).position
                               - a.camera("/World/Cameras/CrowdCam", 12.0).position, [0, 0, 3.0], atol=1e-5)
    lamp = [lt for lt in b.lights if lt.kind == "sphere"]
    assert lamp and lamp[0].intensity == pytest.approx(50.0)
    assert "/World/Props/Crate" in [s.path for s in b.scenery]

    # The final renderer's ground truth from above: the deactivated character is gone, the moved one moved.
    out = tmp_path / "render"
    assert main(["render", str(shot / "shot.usda"), "-o", str(out), "--camera", "/World/Cameras/Overview",
                 "--frames", "12", "--resolution", "160x90", "--spp", "1", "--people-spp", "0",
                 "--no-denoise", "--no-progress"]) == 0
    seen = {r[1] for r in read_mot(out / "mot" / "gt" / "gt.txt")}
    assert ids[agents[1]] not in seen and ids[agents[2]] in seen


BLENDER_SCRIPT = '''
import bpy, json, sys
out = {}
for path in sys.argv[1:]:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.usd_import(filepath=path)
    rec = {"roots": {}, "cameras": {}, "materials": []}
    for f in (1, 12, 24):
        bpy.context.scene.frame_set(f)
        for o in bpy.data.objects:
            if o.type == "ARMATURE":
                rec["roots"].setdefault(o.name, []).append(list((o.matrix_world @ o.pose.bones[0].matrix).translation))
            elif o.type == "CAMERA":
                rec["cameras"].setdefault(o.name, []).append(list(o.matrix_world.translation))
                rec.setdefault("lens", {})[o.name] = [o.data.lens, o.data.clip_end]
    rec["materials"] = [len([s for s in o.material_slots if s.material]) for o in bpy.data.objects
                        if o.type == "MESH" and o.name.startswith("Body")]
    out[path] = rec
print("RESULT " + json.dumps(out))
'''


@pytest.mark.slow
def test_blender_agrees_with_usdcrowd_on_moved_and_placed_shots(museum_shot, moved_shot, tmp_path):
    """Blender (its own importer, no usdcrowd schemas) puts every character's root and every camera where
    usdcrowd's readers do on a moved shot and on one placed in a Y-up centimetre set, and the placed
    bodies come in with their six materials (character.body.REGIONS)."""
    from tests.helpers.venvs import BPY, tool_python

    from usdcrowd.scenario.shot_scene import ShotScene

    from usdcrowd.cli import main

    python = tool_python("bpy", BPY, "USDCROWD_BPY_VENV")
    # Placed now: the lenses place converts are those of the cameras the shot has (tests above add some).
    _, shot = museum_shot
    (tmp_path / "set.usda").write_text(SET)
    placed = tmp_path / "placed.usda"
    assert main(["place", str(shot / "shot.usda"), "--into", str(tmp_path / "set.usda"), "-o", str(placed),
                 "--at", "500", "0", "-300", "--rotate", "40"]) == 0
    script = tmp_path / "layout.py"
    script.write_text(BLENDER_SCRIPT)
    run = subprocess.run([python, str(script), str(moved_shot), str(placed)], capture_output=True, text=True,
                         timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    got = json.loads(next(ln for ln in run.stdout.splitlines() if ln.startswith("RESULT "))[len("RESULT "):])
    for stage in (moved_shot, placed):
        rec, scene = got[str(stage)], ShotScene(stage)
        mine = np.stack([scene.agents(t).joints_world[:, 0, 3, :3] for t in (1.0, 12.0, 24.0)], 1)   # (n, 3, 3)
        mine = mine[scene.agents(1.0).visible]
        theirs = np.array(list(rec["roots"].values()))
        gap = np.linalg.norm(theirs[:, None] - mine[None], axis=-1).max(axis=2)
        assert len(theirs) == len(mine) and len(set(gap.argmin(axis=1).tolist())) == len(mine)
        assert gap.min(axis=1).max() < 1e-4, stage
        for path in scene.camera_paths:
            name = path.rsplit("/", 1)[-1]
            ours = np.array([scene.camera(path, t).position for t in (1.0, 12.0, 24.0)])
            np.testing.assert_allclose(rec["cameras"][name], ours, atol=1e-4, err_msg=f"{stage} {name}")
            view = scene.camera(path, 1.0)
            assert rec["lens"][name] == pytest.approx([view.focal_length, view.far], rel=1e-5), (stage, name)
    assert got[str(placed)]["materials"] and set(got[str(placed)]["materials"]) == {len(REGIONS)}


def test_the_final_renderer_and_its_ground_truth_agree_on_a_moved_shot(museum_shot, moved_shot, tmp_path):
    """The same frame through the same (moved) camera: the same boxes, masks and keypoints to 0.01 px, and
    3D positions and camera extrinsics moved by exactly the layer's transform."""
    from usdcrowd.cli import main
    from usdcrowd.groundtruth.frame_json import read

    _, shot = museum_shot
    records = []
    for stage, out in ((shot / "shot.usda", tmp_path / "a"), (moved_shot, tmp_path / "b")):
        assert main(["render", str(stage), "-o", str(out), "--camera", "/World/Cameras/CrowdCam", "--frames", "12",
                     "--resolution", "160x90", "--spp", "1", "--people-spp", "0", "--no-denoise",
                     "--executor", "inline", "--no-progress"]) == 0
        records.append(read(next((out / "json").glob("*.json"))))
    a, b = records
    assert [x["track_id"] for x in a["agents"]] == [x["track_id"] for x in b["agents"]] and a["agents"]
    for x, y in zip(a["agents"], b["agents"]):
        np.testing.assert_allclose(y["bbox_visible"], x["bbox_visible"], atol=0.01)
        np.testing.assert_allclose(np.array(y["keypoints"], float), np.array(x["keypoints"], float), atol=0.01)
        np.testing.assert_allclose(y["position_3d"], np.array(x["position_3d"]) @ MOVE[:3, :3] + MOVE[3, :3],
                                   atol=1e-4)
        assert y["segmentation"] == x["segmentation"]
    np.testing.assert_allclose(b["camera"]["K"], a["camera"]["K"], atol=1e-9)
    np.testing.assert_allclose(b["camera"]["position"], np.array(a["camera"]["position"]) @ MOVE[:3, :3] + MOVE[3, :3],
                               atol=1e-4)


def test_the_preview_draws_a_moved_shot_as_the_shot(museum_shot, moved_shot, tmp_path, gl):
    """The OpenGL preview through the moved camera: the same ids on the same pixels, depths twice as far
    (the layer scales by 2)."""
    from usdcrowd.cli import main
    from usdcrowd.core.shading import SCENERY_ID_BASE

    _, shot = museum_shot
    aovs = []
    for stage, out in ((shot / "shot.usda", tmp_path / "a"), (moved_shot, tmp_path / "b")):
        assert main(["preview", str(stage), "-o", str(out), "--camera", "/World/Cameras/CrowdCam", "--frames", "12",
                     "--resolution", "320x180", "--aovs", "--no-lod", "--no-progress"]) == 0
        aovs.append(np.load(next(out.glob("*.npz"))))
    a, b = aovs
    people = (a["ids"] > 0) & (a["ids"] < SCENERY_ID_BASE)
    same = a["ids"] == b["ids"]
    assert same.mean() > 0.999 and people.any()
    near = same & np.isfinite(a["depth"])
    np.testing.assert_allclose(b["depth"][near], 2 * a["depth"][near], rtol=1e-3)


def test_events_are_authored_in_their_parents_space_and_read_back_in_the_world(write_stage, tmp_path):
    """A detected event found on a stage whose /World is moved: its centre and radius are written under the
    move and read back where they were found; the same layer under an unmoved /World puts it back off by
    the move (it belongs to the shot's space)."""
    from pxr import Sdf, Usd

    from usdcrowd.core import model
    from usdcrowd.scenario.events import read_events
    from usdcrowd.scenario.parent_space import ParentSpace
    from usdcrowd.scenario.stageio import StageFrame
    from usdcrowd.usd.events import author_events

    moved = write_stage('''
        def Xform "World"
        {
            double3 xformOp:translate = (5, -3, 0)
            float3 xformOp:scale = (2, 2, 2)
            uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:scale"]
        }
        ''', name="moved.usda")
    times = np.arange(1.0, 5.0)
    centre = np.array([[1.0, 2.0, 0.0]] * 4) + np.arange(4)[:, None] * [0.5, 0, 0]
    event = model.Event("/World/Events/Meet_0001", model.EVENT_KINDS.index("groupMotion"), 1.0, 4.0,
                        np.array([], np.int32), times, np.ones((4, 0), bool), centre, np.full(4, 1.5))
    layer = Sdf.Layer.CreateNew(str(tmp_path / "events.usda"))
    with Sdf.ChangeBlock():
        author_events(layer, model.EventTable([event]), [], np.array([]), StageFrame("Z", 1.0),
                      parents=ParentSpace(Usd.Stage.Open(str(moved)), times))
    layer.Save()
    for base, offset, scale in ((moved, np.array([5.0, -3.0, 0.0]), 2.0), (None, np.zeros(3), 1.0)):
        stage_layer = Sdf.Layer.CreateNew(str(tmp_path / f"stage{scale:g}.usda"))
        stage_layer.subLayerPaths = [str(tmp_path / "events.usda")] + ([str(base)] if base else [])
        stage_layer.pseudoRoot.SetInfo("upAxis", "Z")
        stage_layer.pseudoRoot.SetInfo("metersPerUnit", 1.0)
        stage_layer.Save()
        got, = read_events(Usd.Stage.Open(stage_layer), {}, model.TimeRange(1, 4, 24))
        expected = centre if base else (centre - [5.0, -3.0, 0.0]) / 2.0
        np.testing.assert_allclose(got.center, expected, atol=1e-6)
        np.testing.assert_allclose(got.radius, 1.5 if base else 0.75, atol=1e-6)
        assert not got.authored                     # detected, and says so in the layer itself


@pytest.mark.parametrize("case, fix", [
    ("no default prim", lambda set_text: set_text.replace('    defaultPrim = "Set"\n', "")),
    ("too far", None),
    ("not a stage", None),
])
def test_place_refuses_what_would_make_a_broken_stage(museum_shot, tmp_path, capsys, case, fix):
    from usdcrowd.cli import main

    _, shot = museum_shot
    (tmp_path / "set.usda").write_text(fix(SET) if fix else SET)
    out = tmp_path / ("layout.txt" if case == "not a stage" else "layout.usda")
    argv = ["place", str(shot / "shot.usda"), "--into", str(tmp_path / "set.usda"), "-o", str(out)]
    if case == "too far":
        argv += ["--at", "1e12", "0", "0"]
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert not out.exists()


def test_a_shot_placed_twice_keeps_one_track_per_person(museum_shot, tmp_path, capsys):
    """The same shot placed again in a set that holds it: the second copy's ids (and its events' member ids)
    move past the set's, the stage plays the set's frames and the shot's, and it validates clean."""
    from usdcrowd.cli import main
    from usdcrowd.scenario.shot_scene import ShotScene
    from usdcrowd.scenario.stageio import time_range
    from usdcrowd.jobs.summary import agent_list

    _, shot = museum_shot
    (tmp_path / "set.usda").write_text(SET)
    first, second = tmp_path / "once.usda", tmp_path / "twice.usda"
    assert main(["place", str(shot / "shot.usda"), "--into", str(tmp_path / "set.usda"), "-o", str(first)]) == 0
    capsys.readouterr()
    assert main(["place", str(shot / "shot.usda"), "--into", str(first), "-o", str(second), "--at", "0", "0", "800"]) == 0
    assert "/Set/Shot_2" in capsys.readouterr().out
    ids = [a["id"] for a in agent_list(second)]
    original = [a["id"] for a in agent_list(shot / "shot.usda")]
    assert sorted(ids) == sorted(original + [i + 1000 for i in original])
    scene = ShotScene(second)
    assert len(set(scene._agent_static[1].tolist())) == 2 * len(original)
    assert main(["validate", str(second)]) == 0
    assert "0 error(s), 0 warning(s)" in capsys.readouterr().out

    # A set with its own, longer frames keeps them.
    (tmp_path / "long.usda").write_text(SET.replace('    upAxis = "Y"\n', '    upAxis = "Y"\n    startTimeCode = 1\n'
                                                    '    endTimeCode = 100\n'))
    assert main(["place", str(shot / "shot.usda"), "--into", str(tmp_path / "long.usda"), "-o",
                 str(tmp_path / "long_layout.usda")]) == 0
    from usdcrowd.scenario import open_stage
    t = time_range(open_stage(str(tmp_path / "long_layout.usda")))
    assert (t.start, t.end) == (1, 100)


def test_a_placed_shots_lenses_are_in_the_sets_units_for_every_reader(museum_shot, tmp_path):
    """USD does not convert a lens across a reference: place writes each camera's lens and clipping range
    in the set's centimetres, so a flattened copy (what usdview, Blender and any other tool read as it
    is) has the shot's millimetres and metres."""
    from pxr import Usd, UsdGeom

    from usdcrowd.cli import main
    from usdcrowd.scenario.shot_scene import ShotScene

    _, shot = museum_shot
    (tmp_path / "set.usda").write_text(SET)
    placed = tmp_path / "placed.usda"
    assert main(["place", str(shot / "shot.usda"), "--into", str(tmp_path / "set.usda"), "-o", str(placed)]) == 0
    flat = tmp_path / "flat.usdc"
    assert main(["export", str(placed), "--flatten", str(flat), "--no-progress"]) == 0
    a, b = ShotScene(shot / "shot.usda"), ShotScene(flat)
    stage = Usd.Stage.Open(str(flat))
    for pa, pb in zip(a.camera_paths, b.camera_paths):
        ca, cb = a.camera(pa, 12.0), b.camera(pb, 12.0)
        assert (cb.focal_length, cb.horizontal_aperture, cb.near, cb.far) == pytest.approx(
            (ca.focal_length, ca.horizontal_aperture, ca.near, ca.far), rel=1e-6)
        # As plain USD reads it: tenths of the stage's centimetre, which are millimetres.
        cam = UsdGeom.Camera(stage.GetPrimAtPath(pb))
        assert cam.GetFocalLengthAttr().Get(12.0) == pytest.approx(ca.focal_length, rel=1e-6)


def test_validate_says_when_a_placed_shot_was_simulated_again_over_other_frames(tmp_path, capsys):
    from usdcrowd.cli import main

    scenario, shot = cli_museum_shot(tmp_path, agents=4, last_frame=12)
    (tmp_path / "set.usda").write_text(SET)
    layout = tmp_path / "layout.usda"
    assert main(["place", str(shot / "shot.usda"), "--into", str(tmp_path / "set.usda"), "-o", str(layout)]) == 0
    assert main(["simulate", str(scenario), "-o", str(shot), "--frames", "1:20", "--no-progress"]) == 0
    capsys.readouterr()
    assert main(["validate", str(layout)]) == 0
    out = capsys.readouterr().out
    assert "1-20" in out and "place it again" in out
