"""usdcrowd export: a shot as one flattened layer, a usdz package and binary glTF, read back by other readers.

The GLB is read here with nothing of ours: its chunks and accessors with
struct and numpy, its node transforms composed from the glTF spec's own
formulas, and compared with what ShotScene (the renderers' reader) says.
"""

from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from usdcrowd.cli import main

FRAMES = (1, 20)
CLIP_WINDOW = 6                 # windows 1-6, 7-12, 13-18, 19-20


# ------------------------------------------------------------------ fixtures
@pytest.fixture(scope="module")
def shot(tmp_path_factory) -> Path:
    """A museum shot made by `usdcrowd new` and `simulate` (12 agents, 30 frames, a moving CrowdCam)."""
    from tests.helpers.shots import cli_museum_shot

    _, folder = cli_museum_shot(tmp_path_factory.mktemp("export_shot"), 12, 30)
    return folder / "shot.usda"


@pytest.fixture(scope="module")
def clipped_shot(tmp_path_factory) -> Path:
    """The museum's agents walking for 20 frames, their samples in value clips of 6 frames."""
    from tests.helpers.frames import straight_walk

    from usdcrowd.jobs.pipeline import author_shot
    from usdcrowd.core.resources import data_dir

    def walk(sc):
        yield straight_walk(sc.agents, sc.time)

    out = tmp_path_factory.mktemp("export_clipped") / "shot"
    made = author_shot(data_dir("stages") / "museum.usda", out, walk, frames=FRAMES, progress=False,
                       events=False, clip_frames=CLIP_WINDOW)
    assert (out / "crowd.clips").is_dir()
    return Path(made.shot)


def _export(*argv) -> int:
    return main(["export", *map(str, argv), "--no-progress"])


# ------------------------------------------------------------------ GLB, read with struct and numpy
def read_glb(path: Path) -> tuple[dict, bytes]:
    """The JSON and the binary chunk of a GLB (glTF 2.0 spec, "GLB File Format Specification")."""
    data = path.read_bytes()
    magic, version, length = struct.unpack_from("<4sII", data, 0)
    assert (magic, version, length) == (b"glTF", 2, len(data))
    json_length, json_type = struct.unpack_from("<I4s", data, 12)
    assert json_type == b"JSON"
    doc = json.loads(data[20:20 + json_length])
    bin_length, bin_type = struct.unpack_from("<I4s", data, 20 + json_length)
    assert bin_type == b"BIN\0"
    return doc, data[28 + json_length:28 + json_length + bin_length]


def accessor(doc: dict, blob: bytes, index: int) -> np.ndarray:
    """(count, width) values of an accessor (tightly packed views, as usdcrowd writes them)."""
    acc = doc["accessors"][index]
    view = doc["bufferViews"][acc["bufferView"]]
    assert "byteStride" not in view
    dtype = {5126: np.float32, 5125: np.uint32, 5123: np.uint16, 5121: np.uint8}[acc["componentType"]]
    width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}[acc["type"]]
    start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    return np.frombuffer(blob, dtype, acc["count"] * width, start).reshape(acc["count"], width)


def quat_matrix(x, y, z, w) -> np.ndarray:
    """3x3 column-vector rotation of a unit quaternion (x, y, z, w)."""
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def node_worlds(doc: dict, blob: bytes, key: int) -> list[np.ndarray]:
    """Every node's (4, 4) column-vector world matrix at animation key ``key`` (glTF's axes)."""
    trs = [{"translation": n.get("translation", [0, 0, 0]), "rotation": n.get("rotation", [0, 0, 0, 1]),
            "scale": n.get("scale", [1, 1, 1])} for n in doc["nodes"]]
    for anim in doc.get("animations", []):
        for channel in anim["channels"]:
            sampler = anim["samplers"][channel["sampler"]]
            trs[channel["target"]["node"]][channel["target"]["path"]] = accessor(doc, blob, sampler["output"])[key]
    local = []
    for n, values in zip(doc["nodes"], trs):
        m = np.eye(4)
        if "matrix" in n:
            m = np.array(n["matrix"]).reshape(4, 4).T
        else:
            m[:3, :3] = quat_matrix(*values["rotation"]) * np.asarray(values["scale"])
            m[:3, 3] = values["translation"]
        local.append(m)
    parent = {c: i for i, n in enumerate(doc["nodes"]) for c in n.get("children", [])}
    world = [None] * len(local)

    def resolve(i):
        if world[i] is None:
            world[i] = local[i] if i not in parent else resolve(parent[i]) @ local[i]
        return world[i]

    return [resolve(i) for i in range(len(local))]


def z_up(p) -> np.ndarray:
    """glTF (x, y, z), Y up, back to usdcrowd's Z up: (x, -z, y)."""
    p = np.asarray(p, dtype=np.float64)
    return np.stack([p[..., 0], -p[..., 2], p[..., 1]], axis=-1)


def agent_nodes(doc: dict) -> dict[str, int]:
    """{USD path: node} of the agents under the ``crowd`` node."""
    crowd = next(n for n in doc["nodes"] if n.get("name") == "crowd")
    return {doc["nodes"][i]["extras"]["usdPath"]: i for i in crowd["children"]}


# ------------------------------------------------------------------ flatten
PLAIN_USD = r'''
import json, sys
from pxr import Usd, UsdSkel, UsdValidation
stage = Usd.Stage.Open(sys.argv[1])
out = {"clips": [str(p.GetPath()) for p in stage.Traverse() if p.HasMetadata("clips")],
       "layers": [l.identifier for l in stage.GetUsedLayers() if not l.anonymous], "range": [stage.GetStartTimeCode(),
       stage.GetEndTimeCode()], "anims": {}}
for prim in stage.Traverse():
    if prim.IsA(UsdSkel.Animation):
        attr = UsdSkel.Animation(prim).GetTranslationsAttr()
        out["anims"][str(prim.GetPath())] = {str(t): [list(v) for v in attr.Get(t)] for t in attr.GetTimeSamples()}
validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
errors = [e for e in UsdValidation.ValidationContext(validators).Validate(stage) if not e.HasNoError()]
out["validation"] = [e.GetMessage() for e in errors]
out["validators"] = len(validators)
print(json.dumps(out))
'''


def plain_usd(path: Path) -> dict:
    """What usd-core alone (no usdcrowd, no schema plugins) reads in ``path``, and its validators' findings."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("PXR_")}
    run = subprocess.run([sys.executable, "-c", PLAIN_USD, str(path)], capture_output=True, text=True, env=env,
                         timeout=120, cwd=path.parent)
    assert run.returncode == 0, run.stderr[-2000:]
    return json.loads(run.stdout.splitlines()[-1])


def translations(stage_path: Path, frames) -> dict[str, np.ndarray]:
    """{animation prim: (t, 3, 3) joint translations} composed by usdcrowd's USD (clips resolved)."""
    from pxr import Usd, UsdSkel

    stage = Usd.Stage.Open(str(stage_path))
    return {str(p.GetPath()): np.array([UsdSkel.Animation(p).GetTranslationsAttr().Get(float(t)) for t in frames])
            for p in stage.Traverse() if p.IsA(UsdSkel.Animation)}


def test_flatten_resolves_value_clips_into_one_layer_plain_usd_reads(clipped_shot, tmp_path):
    out = tmp_path / "flat.usdc"
    assert _export(clipped_shot, "--flatten", out) == 0
    got = plain_usd(out)
    assert got["layers"] == [str(out)]
    assert got["clips"] == [] and got["range"] == [1.0, 20.0]
    assert got["validators"] > 10 and got["validation"] == []
    frames = range(FRAMES[0], FRAMES[1] + 1)
    original = translations(clipped_shot, frames)
    assert len(original) == 19 and set(got["anims"]) == set(original)
    for path, values in original.items():
        samples = got["anims"][path]
        # Every frame a sample of its own (frames 7, 13, 19 begin a new clip), the clips' values.
        assert sorted(map(float, samples)) == [float(f) for f in frames]
        np.testing.assert_array_equal(np.array([samples[str(float(f))] for f in frames]), values.astype(np.float32))


def test_flatten_with_frames_keeps_the_values_of_those_frames_only(clipped_shot, tmp_path):
    from pxr import Sdf, Usd

    out = tmp_path / "some.usda"
    assert _export(clipped_shot, "--flatten", out, "--frames", "3:15x4") == 0
    layer = Sdf.Layer.FindOrOpen(str(out))
    assert (layer.startTimeCode, layer.endTimeCode) == (3.0, 15.0)
    original = Usd.Stage.Open(str(clipped_shot))
    flat = Usd.Stage.Open(layer)
    sampled = [p for p in flat.Traverse() for a in p.GetAttributes() if a.GetNumTimeSamples()]
    assert sampled
    for prim in flat.Traverse():
        for attr in prim.GetAttributes():
            if not attr.GetNumTimeSamples():
                continue
            assert attr.GetTimeSamples() == [3.0, 7.0, 11.0, 15.0], attr.GetPath()
            source = original.GetAttributeAtPath(attr.GetPath())
            for t in (3.0, 7.0, 11.0, 15.0):
                assert attr.Get(t) == source.Get(t), (attr.GetPath(), t)
    # Where it came from is kept; the shot's relative scenario path, meaningless here, is not.
    data = dict(layer.customLayerData["usdcrowd"])
    assert data["exportedFrom"] == str(clipped_shot) and "scenario" not in data and "seed" in data


# ------------------------------------------------------------------ the exported shots read as the original
def _inspect(stage: Path, capsys) -> dict:
    """``inspect --json`` without what names the files (the stage, its layers). Whether each event was
    authored stays: detected events say so themselves (``crowd:detected``), flattened or not."""
    capsys.readouterr()
    assert main(["inspect", "--json", str(stage)]) == 0
    summary = json.loads(capsys.readouterr().out)
    del summary["stage"], summary["layers"]
    return summary


def _render(stage: Path, out: Path) -> tuple[str, list]:
    """MOT ground truth and COCO annotations (ids, boxes, keypoints, masks) of frame 5, 64x36, 1 spp."""
    assert main(["render", str(stage), "-o", str(out), "--frames", "5", "--resolution", "64x36", "--spp", "1",
                 "--people-spp", "0", "--executor", "inline", "--no-progress"]) == 0
    coco = json.loads((out / "coco.json").read_text())
    return (out / "mot" / "gt" / "gt.txt").read_text(), coco["annotations"]


def test_flattened_and_packaged_shots_inspect_validate_and_render_as_the_original(shot, tmp_path, capsys):
    flat, usdz = tmp_path / "flat.usdc", tmp_path / "shot.usdz"
    assert _export(shot, "--flatten", flat, "--usdz", usdz) == 0
    import zipfile

    assert zipfile.ZipFile(usdz).namelist() == ["shot.usdc"]
    assert plain_usd(usdz)["validation"] == []              # the usdz rules included
    before = _inspect(shot, capsys)
    assert before["agents"]["count"] == 12 and before["cameras"]
    gt, annotations = _render(shot, tmp_path / "render_shot")
    assert len(annotations) >= 3 and gt.count("\n") == len(annotations)
    for exported in (flat, usdz):
        assert _inspect(exported, capsys) == before
        assert main(["validate", str(exported)]) == 0
        assert capsys.readouterr().out.strip().endswith("0 error(s), 0 warning(s)")
        assert _render(exported, tmp_path / f"render_{exported.suffix[1:]}") == (gt, annotations)


def test_a_usdz_package_of_the_layered_shot_is_read_through_its_inner_paths(clipped_shot, tmp_path, capsys):
    """UsdUtils packages shot.usda with its sublayers and clips (``pkg.usdz[crowd.usdc]`` inside): every
    layer it names is checked as the package file, and read from within it."""
    import zipfile

    from pxr import UsdUtils

    from usdcrowd.scenario.shot_scene import ShotScene

    package = tmp_path / "layered.usdz"
    assert UsdUtils.CreateNewUsdzPackage(str(clipped_shot), str(package))
    inner = zipfile.ZipFile(package).namelist()
    assert "cameras.usda" in inner and any("crowd.clips" in n or n.endswith(".0001.usdc") for n in inner)
    assert main(["validate", str(package)]) == 0
    assert capsys.readouterr().out.strip().endswith("0 error(s), 0 warning(s)")
    assert _inspect(package, capsys)["agents"] == _inspect(clipped_shot, capsys)["agents"]
    a, b = ShotScene(clipped_shot), ShotScene(package)
    assert a.agent_paths == b.agent_paths and a.camera_paths == b.camera_paths
    for t in (1, 12, 13, 20):                                 # across the clips' windows
        np.testing.assert_array_equal(a.agents(t).joints_world, b.agents(t).joints_world)


def test_a_usdz_carries_the_behavior_map_images_and_they_are_read_from_it(tmp_path, capsys):
    """A painted behavior layer's image travels inside the package; inspect and validate read it there."""
    import zipfile

    scenario, folder = tmp_path / "harbour.usda", tmp_path / "shot"
    assert main(["new", "harbour", "-o", str(scenario), "--agents", "6"]) == 0
    assert main(["simulate", str(scenario), "-o", str(folder), "--frames", "1:3", "--no-progress"]) == 0
    usdz = tmp_path / "harbour.usdz"
    assert _export(folder / "shot.usda", "--usdz", usdz) == 0
    (scenario.parent / "maps").rename(tmp_path / "moved")          # only the package's copy is left
    assert zipfile.ZipFile(usdz).namelist() == ["harbour.usdc", "0/harbour_water.png"]
    assert main(["validate", str(usdz)]) == 0
    assert capsys.readouterr().out.strip().endswith("0 error(s), 0 warning(s)")
    layers = _inspect(usdz, capsys)["behaviorLayers"]
    (tmp_path / "moved").rename(scenario.parent / "maps")
    assert layers and layers == _inspect(folder / "shot.usda", capsys)["behaviorLayers"]


# ------------------------------------------------------------------ glTF
@pytest.fixture(scope="module")
def glb(shot, tmp_path_factory) -> tuple[Path, np.ndarray]:
    """The shot as GLB, frames 2 to 20 every 3rd: (path, the frames)."""
    out = tmp_path_factory.mktemp("glb") / "shot.glb"
    assert _export(shot, "--gltf", out, "--frames", "2:20x3") == 0
    return out, np.arange(2.0, 21.0, 3.0)


def test_gltf_joints_follow_the_agents_at_each_frame(glb, shot):
    from usdcrowd.scenario.shot_scene import ShotScene

    path, frames = glb
    doc, blob = read_glb(path)
    scene = ShotScene(shot)
    times = {tuple(accessor(doc, blob, s["input"])[:, 0]) for a in doc["animations"] for s in a["samplers"]}
    assert len(times) == 1                                   # one clock, in seconds from the first frame
    np.testing.assert_allclose(np.array(times.pop()), (frames - 2.0) / 24.0, atol=1e-6)
    assert doc["asset"]["extras"]["usdcrowd"]["frames"] == frames.tolist()
    agents = agent_nodes(doc)
    poses = {f: scene.agents(f) for f in frames}
    visible = [p for p, v in zip(scene.agent_paths, poses[frames[0]].visible) if v]
    assert sorted(agents) == sorted(visible) and len(visible) == 11      # the invisible leader left out
    for key, frame in enumerate(frames):
        worlds = node_worlds(doc, blob, key)
        for path_, node in agents.items():
            row = scene.agent_row(path_)
            legs = doc["nodes"][node]["children"][0]
            torso = doc["nodes"][legs]["children"][0]
            head = doc["nodes"][torso]["children"][0]
            got = z_up(np.array([worlds[j][:3, 3] for j in (legs, torso, head)]))
            np.testing.assert_allclose(got, poses[frame].joints_world[row, :, 3, :3], atol=1e-4)
            assert doc["nodes"][node]["extras"]["agentId"] == int(poses[frame].agent_ids[row])


def test_gltf_skinned_body_matches_the_renderers_vertices(glb, shot):
    """Linear blend skinning by the spec (joint world @ inverse bind, weighted) gives the body the
    renderers draw, for each agent, at a frame in the middle."""
    from usdcrowd.scenario.shot_scene import ShotScene

    path, frames = glb
    doc, blob = read_glb(path)
    scene = ShotScene(shot)
    key, frame = 4, frames[4]
    worlds = node_worlds(doc, blob, key)
    poses = scene.agents(frame)
    skinned = scene.skinned_vertices(poses)
    bodies = {doc["nodes"][i]["name"]: doc["nodes"][i] for i in doc["scenes"][0]["nodes"] if "skin" in doc["nodes"][i]}
    assert len(bodies) == len(agent_nodes(doc))
    for path_ in agent_nodes(doc):
        node = bodies[f"{path_}/Body"]
        skin = doc["skins"][node["skin"]]
        prim = doc["meshes"][node["mesh"]]["primitives"][0]
        points = accessor(doc, blob, prim["attributes"]["POSITION"]).astype(np.float64)
        joints = accessor(doc, blob, prim["attributes"]["JOINTS_0"]).astype(int)
        weights = accessor(doc, blob, prim["attributes"]["WEIGHTS_0"]).astype(np.float64)
        inverse_binds = accessor(doc, blob, skin["inverseBindMatrices"]).reshape(-1, 4, 4).transpose(0, 2, 1)
        joint_mats = np.array([worlds[j] for j in skin["joints"]]) @ inverse_binds          # (3, 4, 4)
        homogeneous = np.c_[points, np.ones(len(points))]
        moved = np.einsum("vk,vkij,vj->vi", weights, joint_mats[joints], homogeneous)[:, :3]
        np.testing.assert_allclose(z_up(moved), skinned[scene.agent_row(path_)], atol=1e-4)
        # Its colours: the agent's palette, region by region (linear RGB, as USD's displayColor).
        colours = accessor(doc, blob, prim["attributes"]["COLOR_0"])
        np.testing.assert_allclose(colours, poses.palette[scene.agent_row(path_)][scene.body.regions], atol=1e-6)


def test_gltf_cameras_look_where_the_shot_cameras_look(glb, shot):
    from usdcrowd.scenario.shot_scene import ShotScene
    from usdcrowd.core.view import fov

    path, frames = glb
    doc, blob = read_glb(path)
    scene = ShotScene(shot)
    cameras = {n["name"]: i for i, n in enumerate(doc["nodes"]) if "camera" in n}
    assert sorted(cameras) == sorted(scene.camera_paths)
    moved = 0
    for key, frame in enumerate(frames):
        worlds = node_worlds(doc, blob, key)
        for cam_path, node in cameras.items():
            view = scene.camera(cam_path, frame)
            np.testing.assert_allclose(z_up(worlds[node][:3, 3]), view.cam_to_world[3, :3], atol=1e-4)
            # glTF cameras look down their local -Z, as USD's.
            np.testing.assert_allclose(z_up(-worlds[node][:3, 2]), -view.cam_to_world[2, :3], atol=1e-5)
            np.testing.assert_allclose(z_up(worlds[node][:3, 1]), view.cam_to_world[1, :3], atol=1e-5)
            lens = doc["cameras"][doc["nodes"][node]["camera"]]["perspective"]
            assert lens["yfov"] == pytest.approx(float(fov(view.focal_length, view.vertical_aperture)), rel=1e-6)
            assert lens["aspectRatio"] == pytest.approx(view.horizontal_aperture / view.vertical_aperture)
            moved += key > 0 and not np.allclose(worlds[node][:3, 3], node_worlds(doc, blob, 0)[node][:3, 3])
    assert moved                                             # the CrowdCam follows the crowd


def test_gltf_loads_in_trimesh_with_the_scenery_in_place(glb, shot):
    import trimesh

    from usdcrowd.scenario.shot_scene import ShotScene

    path, _ = glb
    scene = ShotScene(shot)
    loaded = trimesh.load(path)
    doc, _blob = read_glb(path)
    assert len(loaded.geometry) == len(agent_nodes(doc)) + len(scene.scenery)
    for item in scene.scenery:
        world = item.local_to_world(2.0)
        expected = item.mesh.vertices @ world[:3, :3] + world[3, :3]
        name = next(n for n in loaded.graph.nodes_geometry if loaded.graph[n][1] == item.path or n == item.path)
        transform, geometry = loaded.graph[name]
        got = trimesh.transform_points(loaded.geometry[geometry].vertices, transform)
        np.testing.assert_allclose(z_up(got), expected, atol=1e-4)
    body = loaded.geometry[f"{scene.agent_paths[1]}/Body"]
    assert len(body.vertices) == len(scene.body.points) and len(body.faces) == len(scene.body.faces)
    # Standing upright in glTF's Y-up: from the feet (y ~ 0) to the head.
    assert body.bounds[0][1] == pytest.approx(0.0, abs=0.05) and 1.6 < body.bounds[1][1] < 1.9


def test_an_agent_hidden_at_some_frames_is_scaled_to_nothing_there(shot, tmp_path):
    from pxr import Sdf, UsdGeom

    from usdcrowd.scenario.shot_scene import ShotScene

    scene = ShotScene(shot)
    hidden = next(p for p, v in zip(scene.agent_paths, scene.agents(1).visible) if v)
    edit = tmp_path / "edit.usda"
    layer = Sdf.Layer.CreateNew(str(edit))
    layer.subLayerPaths = [str(shot)]
    layer.startTimeCode, layer.endTimeCode = 1, 30
    attr = Sdf.AttributeSpec(Sdf.CreatePrimInLayer(layer, hidden), UsdGeom.Tokens.visibility, Sdf.ValueTypeNames.Token)
    for t, value in ((1, "inherited"), (10, "invisible"), (20, "inherited")):
        layer.SetTimeSample(attr.path, t, value)
    layer.Save()
    out = tmp_path / "hidden.glb"
    assert _export(edit, "--gltf", out, "--frames", "1:30") == 0
    doc, blob = read_glb(out)
    node = agent_nodes(doc)[hidden]
    (channel, sampler), = [(c, a["samplers"][c["sampler"]]) for a in doc["animations"] for c in a["channels"]
                           if c["target"]["node"] == node]
    assert channel["target"]["path"] == "scale" and sampler["interpolation"] == "STEP"
    scale = accessor(doc, blob, sampler["output"])[:, 0]
    np.testing.assert_array_equal(np.flatnonzero(scale == 0) + 1, np.arange(10, 20))


# ------------------------------------------------------------------ the command's rules
def test_export_refuses_bad_requests_in_one_line(shot, tmp_path, capsys):
    cases = [
        ([], "name an output"),
        (["--gltf", tmp_path / "x.gltf"], "name it *.glb"),
        (["--usdz", tmp_path / "x.usdc"], "name it *.usdz"),
        (["--flatten", tmp_path / "x.usdc", "--frames", "25:40"], "frame 31 is outside"),
        (["--flatten", shot], "would overwrite an input"),
        (["--flatten", shot.parent / "crowd.usdc"], "would overwrite an input"),
    ]
    for extra, message in cases:
        capsys.readouterr()
        assert _export(shot, *extra) == 2, extra
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and message in err, (extra, err)
    assert _export(tmp_path / "missing.usda", "--gltf", tmp_path / "m.glb") == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "missing.usda" in err
    assert not list(tmp_path.glob("x.*")) and not list(tmp_path.glob("*.glb"))


def test_gltf_without_pygltflib_is_one_line_naming_the_extra(shot, tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "pygltflib", None)          # as if not installed
    assert _export(shot, "--gltf", tmp_path / "n.glb") == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "usdcrowd[preview]" in err and not (tmp_path / "n.glb").exists()


def test_export_replaces_only_its_own_outputs_unless_forced(shot, tmp_path, capsys):
    out = tmp_path / "mine.glb"
    out.write_bytes(b"someone else's")
    assert _export(shot, "--gltf", out, "--frames", "1:3") == 2
    assert "not written by usdcrowd" in capsys.readouterr().err and out.read_bytes() == b"someone else's"
    assert _export(shot, "--gltf", out, "--frames", "1:3", "--force") == 0
    assert read_glb(out)[0]["asset"]["extras"]["usdcrowd"]["frames"] == [1.0, 2.0, 3.0]
    assert _export(shot, "--gltf", out, "--frames", "4:5") == 0          # its own now: replaced freely
    assert read_glb(out)[0]["asset"]["extras"]["usdcrowd"]["frames"] == [4.0, 5.0]


@pytest.mark.parametrize("output", ["--flatten", "--usdz", "--gltf"])
def test_a_failed_write_leaves_the_previous_output_whole(shot, tmp_path, monkeypatch, capsys, output):
    """A write that fails half way (the disk full) leaves what was there and no temporary file."""
    import errno

    import pygltflib
    from pxr import Sdf, UsdUtils

    out = tmp_path / {"--flatten": "f.usdc", "--usdz": "f.usdz", "--gltf": "f.glb"}[output]
    assert _export(shot, output, out, "--frames", "1:2") == 0
    before = out.read_bytes()

    def half_then_fail(*args):
        target = args[-1] if not isinstance(args[-1], Sdf.AssetPath) else args[0]
        Path(os.fspath(target)).write_bytes(b"half")
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(pygltflib.GLTF2, "save_binary", half_then_fail)
    monkeypatch.setattr(UsdUtils, "CreateNewUsdzPackage", half_then_fail)
    monkeypatch.setattr(Sdf.Layer, "Export", lambda self, path, *a, **k: half_then_fail(path))
    assert _export(shot, output, out, "--frames", "3:4") == 2
    assert "no space left on device" in capsys.readouterr().err
    assert out.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir() if not p.name.startswith(".usdcrowd")) == [out.name]


def test_long_exports_show_progress(shot, tmp_path, capsys):
    capsys.readouterr()
    assert main(["export", str(shot), "--gltf", str(tmp_path / "p.glb"), "--flatten", str(tmp_path / "p.usdc"),
                 "--frames", "1:30x2"]) == 0
    err = capsys.readouterr().err
    assert "export glTF:" in err and "/15 [" in err and "export frames:" in err      # 15 frames
    assert _export(shot, "--gltf", tmp_path / "q.glb") == 0
    assert capsys.readouterr().err == ""


# ------------------------------------------------------------------ Blender
BLENDER_SCRIPT = '''
import json, sys
import bpy
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_scene.gltf(filepath=sys.argv[1])
scene = bpy.context.scene
arms = [o for o in bpy.data.objects if o.type == "ARMATURE"]
roots = {}
for f in json.loads(sys.argv[2]):
    scene.frame_set(f)
    for o in arms:
        roots.setdefault(o.name, []).append(list(o.matrix_world @ o.pose.bones["legs"].head))
print("RESULT " + json.dumps(roots))
'''


@pytest.mark.slow
def test_blender_imports_the_glb_with_the_agents_in_place(glb, shot, tmp_path):
    """Blender's own glTF importer: each armature's root bone where usdcrowd's agent stands (Blender puts
    glTF's second 0 at its frame 0 and turns Y up back to Z up)."""
    from tests.helpers.venvs import BPY, tool_python

    from usdcrowd.scenario.shot_scene import ShotScene

    python = tool_python("bpy", BPY, "USDCROWD_BPY_VENV")
    path, frames = glb
    script = tmp_path / "import_glb.py"
    script.write_text(BLENDER_SCRIPT)
    keys = [0, 9, 18]                                    # seconds 0, 0.375, 0.75 at 24 fps: frames 2, 11, 20
    run = subprocess.run([python, str(script), str(path), json.dumps(keys)], capture_output=True, text=True,
                         timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    roots = json.loads(next(ln for ln in run.stdout.splitlines() if ln.startswith("RESULT "))[len("RESULT "):])
    scene = ShotScene(shot)
    assert len(roots) == 11
    for name, heads in roots.items():
        row = scene.agent_row(name)
        expected = [scene.agents(2 + k).joints_world[row, 0, 3, :3] for k in keys]
        np.testing.assert_allclose(np.array(heads), np.array(expected), atol=1e-4)
