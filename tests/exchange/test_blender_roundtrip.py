"""A shot back from Blender (#29, 6): usdcrowd knows its agents by the ids they carry as custom properties.

A layout artist imports a usdcrowd shot into Blender, moves a camera, deletes
an agent and exports the scene (``usd_export`` with animation). The export
has none of our schemas: agents are SkelRoots carrying ``crowd:agentId`` as a
custom property, each Skeleton under a transform of its own with its
animation bound on it. ``inspect``, ``validate`` and ``render`` read it, and
the ground truth keeps the agents' original track ids and boxes.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest

from tests.helpers.shots import cli_museum_shot

FRAMES = "1:24x11"                    # frames 1, 12 and 23
RENDER = ["--frames", FRAMES, "--spp", "1", "--people-spp", "0", "--no-denoise", "--no-progress"]

# What the artist does in Blender: import, move the Overview camera (straight down, over the crowd), delete
# the agent whose crowd:agentId is given, with its armature and body, and export with animation.
ROUND_TRIP_SCRIPT = '''
import sys
import bpy
from mathutils import Matrix
shot, out, agent_id = sys.argv[1], sys.argv[2], int(sys.argv[3])
above = [float(v) for v in sys.argv[4].split(",")]
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.wm.usd_import(filepath=shot)
bpy.data.objects["Overview"].matrix_world = Matrix.Translation(above)
agent = next(o for o in bpy.data.objects if o.get("crowd:agentId") == agent_id)
for o in [*agent.children_recursive, agent]:
    bpy.data.objects.remove(o, do_unlink=True)
bpy.ops.wm.usd_export(filepath=out, export_animation=True)
'''


def _agents(shot) -> dict[int, str]:
    """Original track id -> prim path of every agent ``inspect --agents`` lists."""
    from usdcrowd.jobs.summary import agent_list

    return {a["id"]: a["path"] for a in agent_list(shot)}


def _render(shot, out: Path, camera: str, resolution: str) -> dict[tuple[int, int], np.ndarray]:
    """(frame, track id) -> MOT box [left, top, width, height] of ``usdcrowd render`` through ``camera``."""
    from usdcrowd.cli import main
    from usdcrowd.groundtruth.mot import read_mot

    assert main(["render", str(shot), "-o", str(out), "--camera", camera, "--resolution", resolution, *RENDER]) == 0
    return {(r[0], r[1]): np.array(r[2:6]) for r in read_mot(out / "mot" / "gt" / "gt.txt")}


def _keypoints(out: Path) -> dict[tuple[int, int], np.ndarray]:
    """(frame, track id) -> (k, 3) COCO keypoints (x, y, flag) of a render's ``coco.json``."""
    import json

    coco = json.loads((out / "coco.json").read_text())
    frame = {im["id"]: im["frame_index"] for im in coco["images"]}
    return {(frame[a["image_id"]], a["track_id"]): np.array(a["keypoints"]).reshape(-1, 3)
            for a in coco["annotations"]}


def _above_the_crowd(shot) -> str:
    """A point high enough over the crowd that a camera looking straight down sees everyone at every frame."""
    from usdcrowd.scenario.shot_scene import ShotScene

    scene = ShotScene(shot)
    heads = np.concatenate([scene.agents(t).joints_world[:, 2, 3, :3] for t in scene.time_codes])
    lo, hi = heads.min(axis=0), heads.max(axis=0)
    # The Overview lens: 24 mm over a 36 x 20.25 mm aperture, so tan(half field) is 0.75 by 0.42.
    height = hi[2] + 1.3 * max((hi[0] - lo[0]) / 2 / 0.75, (hi[1] - lo[1]) / 2 / 0.42) + 2.0
    return ",".join(f"{v:.3f}" for v in ((lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, height))


@pytest.fixture(scope="module")
def round_trip(tmp_path_factory):
    """(original shot, the shot back from Blender, id of the agent deleted there), made as a user makes them."""
    from tests.helpers.venvs import BPY, tool_python

    python = tool_python("bpy", BPY, "USDCROWD_BPY_VENV")
    folder = tmp_path_factory.mktemp("round_trip")
    _, shot_dir = cli_museum_shot(folder, agents=10, last_frame=24)
    shot = shot_dir / "shot.usda"
    deleted = 106
    assert deleted in _agents(shot)
    script = folder / "round_trip.py"
    script.write_text(ROUND_TRIP_SCRIPT)
    back = folder / "from_blender.usd"
    run = subprocess.run([python, str(script), str(shot), str(back), str(deleted), _above_the_crowd(shot)],
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0 and back.is_file(), run.stderr[-2000:]
    return shot, back, deleted


def _camera(shot, name: str) -> str:
    from usdcrowd.scenario.shot_scene import ShotScene

    (path,) = [p for p in ShotScene(shot).camera_paths if p.rsplit("/", 1)[-1] == name]
    return path


@pytest.mark.slow
def test_the_shot_back_from_blender_renders_with_the_original_track_ids_and_boxes(round_trip, tmp_path):
    shot, back, deleted = round_trip
    from usdcrowd.scenario.shot_scene import ShotScene

    visible = ShotScene(shot).agents(1)
    survivors = {int(i) for i, seen in zip(visible.agent_ids, visible.visible) if seen} - {deleted}
    # Blender renames prims (clone_0000 -> clone_0000_001) and orders them its own way: ids are not their rows.
    assert sorted(ShotScene(back)._agent_static[1]) == sorted(survivors)

    # The moved camera looks down on the whole crowd: every agent left has its own track, under its own id.
    moved = _render(back, tmp_path / "moved", _camera(back, "Overview"), "192x108")
    frames = sorted({f for f, _ in moved})
    assert len(frames) == 3
    assert {f: {i for g, i in moved if g == f} for f in frames} == {f: survivors for f in frames}

    # Through the camera nobody moved, the agents are where they were: the same boxes, to a pixel.
    original = _render(shot, tmp_path / "original", "/World/Cameras/CrowdCam", "160x90")
    again = _render(back, tmp_path / "again", _camera(back, "CrowdCam"), "160x90")
    assert {k for k in original if k[1] != deleted} == set(again) and len(again) > 6
    worst = max(np.abs(original[k] - again[k]).max() for k in again)
    assert worst <= 1.0, worst
    # And so are their keypoints (where both renders label them: the deleted agent no longer hides anyone).
    before, after = _keypoints(tmp_path / "original"), _keypoints(tmp_path / "again")
    assert set(after) <= set(before) and len(after) > 6
    for k, kp in after.items():
        labelled = (kp[:, 2] > 0) & (before[k][:, 2] > 0)
        assert labelled.any() and np.abs(kp[labelled, :2] - before[k][labelled, :2]).max() <= 1.0, k


@pytest.mark.slow
def test_inspect_lists_the_agents_back_from_blender_and_validate_says_what_was_lost(round_trip, capsys):
    from usdcrowd.cli import main

    shot, back, deleted = round_trip
    before, after = _agents(shot), _agents(back)
    assert set(after) == set(before) - {deleted, 101}          # 101: the invisible guide Blender leaves out
    for aid, path in after.items():                            # each under its old name (Blender's suffix aside)
        assert path.rsplit("/", 1)[-1].startswith(before[aid].rsplit("/", 1)[-1])

    assert main(["inspect", "--agents", str(back)]) == 0
    rows = capsys.readouterr().out.splitlines()[1:]
    assert sorted(int(r.split()[2]) for r in rows) == sorted(after)
    assert main(["inspect", str(back)]) == 0
    assert f"agents  {len(after)} ({len(after)} visible), ids {min(after)}-{max(after)}" in capsys.readouterr().out

    assert main(["validate", str(back)]) == 0
    said = capsys.readouterr().out
    assert "0 error(s)" in said
    for lost in ("without CrowdAgentAPI", "are no CrowdGroup here", "no longer sampled", "crowd:leader"):
        assert lost in said, lost


def _without_our_schemas(shot, out: Path):
    """The shot flattened into ``out`` as a tool that drops our schemas and groups but keeps
    ``userProperties:crowd:*`` verbatim writes it; returns its (open, unsaved) layer."""
    from pxr import Sdf, Usd

    from usdcrowd.scenario.shot_scene import ShotScene

    Usd.Stage.Open(str(shot)).Export(str(out))
    layer = Sdf.Layer.FindOrOpen(str(out))
    for path in ShotScene(shot).agent_paths:
        spec = layer.GetPrimAtPath(path)
        spec.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["SkelBindingAPI"]))
        spec.RemoveProperty(spec.properties["crowd:agentId"])
        while (spec := spec.nameParent) and spec.typeName == "CrowdGroup":
            spec.typeName = "Xform"
    return layer


def test_agents_that_carry_only_their_user_properties_keep_their_ids(walking_museum, tmp_path):
    """A tool that keeps ``userProperties:crowd:agentId`` as it is, and drops our schemas, still gives the
    agents usdcrowd knew: the same ids, the same joints."""
    from usdcrowd.scenario.shot_scene import ShotScene
    from usdcrowd.jobs.summary import agent_list

    flat = tmp_path / "flat.usda"
    _without_our_schemas(walking_museum, flat).Save()
    ours, theirs = ShotScene(walking_museum), ShotScene(flat)
    assert theirs.agent_paths == ours.agent_paths
    np.testing.assert_array_equal(theirs._agent_static[1], ours._agent_static[1])
    np.testing.assert_allclose(theirs.agents(7).joints_world, ours.agents(7).joints_world, atol=1e-9)
    assert [(a["path"], a["id"]) for a in agent_list(flat)] == list(zip(ours.agent_paths, ours._agent_static[1]))


def test_validate_refuses_an_id_two_agents_carry_and_warns_of_an_agent_without_animation(walking_museum, tmp_path):
    """Duplicating an agent in a DCC tool copies its custom properties, id included: an error, as for any
    agent. An agent exported without its animation is not drawn: a warning that names it."""
    from pxr import Sdf

    from usdcrowd.scenario.shot_scene import ShotScene
    from usdcrowd.jobs.validation import validate

    flat = tmp_path / "flat.usda"
    layer = _without_our_schemas(walking_museum, flat)
    teacher, still = "/World/Crowd/Visitors/Students/Teacher", "/World/Crowd/Guards/clone_0000"
    assert Sdf.CopySpec(layer, teacher, layer, teacher + "Copy")
    layer.GetPrimAtPath(still).RemoveProperty(layer.GetPrimAtPath(still).relationships["skel:animationSource"])
    layer.Save()

    found = validate(flat)
    errors = [(p.prim, p.message) for p in found if p.severity == "error"]
    assert errors == [(teacher + "Copy", f"agent id 100 is also used by {teacher}")]
    assert any(p.prim == still and "no SkelAnimation" in p.message for p in found if p.severity == "warning")
    assert still not in ShotScene(flat).agent_paths
