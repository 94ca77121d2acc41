"""Blender reads our shots as we mean them: its own USD importer (the ``bpy`` wheel, headless, no plugin path)."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest

from tests.helpers.venvs import BPY

pytestmark = pytest.mark.slow

# Imports each shot and prints every armature's root bone head in world space at some frames.
IMPORT_SCRIPT = '''
import json, sys
import bpy
out = {}
for path in sys.argv[2:]:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.usd_import(filepath=path)
    scene = bpy.context.scene
    arms = [o for o in bpy.data.objects if o.type == "ARMATURE"]
    frames = [int(f) for f in sys.argv[1].split(",")]
    roots = {}
    for f in frames:
        scene.frame_set(f)
        for o in arms:
            roots.setdefault(o.name, []).append(list((o.matrix_world @ o.pose.bones[0].matrix).translation))
    out[path] = {"range": [scene.frame_start, scene.frame_end], "roots": roots}
print("RESULT " + json.dumps(out))
'''


@pytest.fixture(scope="module")
def blender_python():
    from tests.helpers.venvs import tool_python

    return tool_python("bpy", BPY, "USDCROWD_BPY_VENV")


def _blender(python: str, tmp_path, frames: list[int], *shots) -> dict:
    script = tmp_path / "import_shots.py"
    script.write_text(IMPORT_SCRIPT)
    run = subprocess.run([python, str(script), ",".join(map(str, frames)), *map(str, shots)],
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    line = next(ln for ln in run.stdout.splitlines() if ln.startswith("RESULT "))
    return json.loads(line[len("RESULT "):])


def test_blender_plays_a_shot_split_in_value_clips_as_the_one_layer_shot(blender_python, museum_path, tmp_path):
    from tests.helpers.frames import straight_walk

    from usdcrowd.jobs.pipeline import author_shot
    from usdcrowd.scenario.crowd import read_crowd

    def walk(sc):
        yield straight_walk(sc.agents, sc.time)

    shots = {}
    for name, window in (("inline", None), ("clipped", 6)):
        shots[name] = author_shot(museum_path, tmp_path / name, walk, frames=(1, 20), progress=False,
                                  events=False, clip_frames=window).shot
    assert (tmp_path / "clipped" / "crowd.clips").is_dir()
    frames = [1, 6, 7, 13, 20]
    got = _blender(blender_python, tmp_path, frames, *shots.values())
    inline, clipped = (got[shots[k]] for k in ("inline", "clipped"))
    assert inline["range"] == clipped["range"] == [1, 20]
    assert inline["roots"].keys() == clipped["roots"].keys() and len(inline["roots"]) > 10
    np.testing.assert_array_equal(np.array(list(clipped["roots"].values())), np.array(list(inline["roots"].values())))
    # And Blender's root bones follow the agents usdcrowd simulated (Blender names the armatures after the
    # Skeleton prims, so they are matched by position: one agent each, at every frame).
    # Invisible agents (the invisible leaders) are not imported.
    crowd, info = read_crowd(shots["clipped"])
    heads = np.array(list(clipped["roots"].values()))[:, :, :2]               # (armatures, frames, 2)
    walked = np.swapaxes(crowd.position[np.array(frames) - 1][:, info.visible, :2], 0, 1)  # (agents, frames, 2)
    gap = np.linalg.norm(heads[:, None] - walked[None], axis=-1).max(axis=2)  # worst frame, per pair
    match = gap.argmin(axis=1)
    assert len(set(match.tolist())) == len(heads) == len(walked)
    assert gap[np.arange(len(heads)), match].max() < 1e-4


LENS_SCRIPT = '''
import bpy, json, sys
exported, shot = sys.argv[1], sys.argv[2]
bpy.ops.wm.read_factory_settings(use_empty=True)
data = bpy.data.cameras.new("Lens35")
data.lens, data.sensor_width, data.sensor_fit = 35.0, 36.0, "HORIZONTAL"
obj = bpy.data.objects.new("Lens35", data)
bpy.context.scene.collection.objects.link(obj)
obj.location = (1.0, -5.0, 1.7)
bpy.ops.wm.usd_export(filepath=exported)
out = {"exported": {"lens": data.lens, "angle_x": data.angle_x}}
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.wm.usd_import(filepath=shot)
out["imported"] = {o.name: {"lens": o.data.lens, "angle_x": o.data.angle_x}
                   for o in bpy.data.objects if o.type == "CAMERA"}
print("RESULT " + json.dumps(out))
'''


def test_lenses_mean_the_same_millimetres_in_blender_and_usdcrowd(blender_python, museum_path, tmp_path):
    """focalLength and the apertures are tenths of a scene unit both ways: a Blender 35 mm lens reads as
    35 mm here, and our cameras reach Blender with the millimetres and field of view we render with."""
    import math

    from tests.helpers.frames import straight_walk

    from usdcrowd.jobs.pipeline import author_shot
    from usdcrowd.scenario.shot_scene import ShotScene

    shot = author_shot(museum_path, tmp_path / "shot", lambda sc: [straight_walk(sc.agents, sc.time)],
                       frames=(1, 4), progress=False, camera_count=2)
    exported = tmp_path / "blender_camera.usda"
    script = tmp_path / "lenses.py"
    script.write_text(LENS_SCRIPT)
    run = subprocess.run([blender_python, str(script), str(exported), shot.shot], capture_output=True, text=True,
                         timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    got = json.loads(next(ln for ln in run.stdout.splitlines() if ln.startswith("RESULT "))[len("RESULT "):])

    theirs = ShotScene(exported)
    view = theirs.camera(theirs.camera_paths[0], 1)
    assert view.focal_length == pytest.approx(35.0, rel=1e-6) and view.horizontal_aperture == pytest.approx(36.0)
    assert math.radians(view.fov_x()) == pytest.approx(got["exported"]["angle_x"], rel=1e-6)

    from usdcrowd.cameras import overview, placement

    # The lenses usdcrowd meant: the overview's, the generated camera agents', the scenario's own (24 mm).
    meant = {"CrowdCam": overview.FOCAL_LENGTH, "Agent01": placement.FOCAL_LENGTH,
             "Agent02": placement.FOCAL_LENGTH, "Overview": 24.0}
    assert {k: round(v["lens"], 3) for k, v in got["imported"].items()} == meant
    ours = ShotScene(shot.shot)
    names = {p.rsplit("/", 1)[-1]: p for p in ours.camera_paths}
    assert set(got["imported"]) == set(names)
    for name, blender in got["imported"].items():
        mine = ours.camera(names[name], 1)
        assert blender["lens"] == pytest.approx(mine.focal_length, rel=1e-5), name
        assert blender["angle_x"] == pytest.approx(math.radians(mine.fov_x()), rel=1e-5), name


HIERARCHY_SCRIPT = '''
import bpy, json, sys
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.wm.usd_import(filepath=sys.argv[1])
frames = [int(f) for f in sys.argv[2].split(",")]
out = {"roots": {}, "chains": {}}
for f in frames:
    bpy.context.scene.frame_set(f)
    for o in bpy.data.objects:
        if o.type == "ARMATURE":
            out["roots"].setdefault(o.name, []).append(list((o.matrix_world @ o.pose.bones[0].matrix).translation))
for o in bpy.data.objects:
    if o.type == "ARMATURE":
        chain, p = [], o.parent
        while p is not None:
            chain.append(p.name)
            p = p.parent
        out["chains"][o.name] = chain
out["props"] = {o.name: {k: v for k, v in o.items() if isinstance(v, (int, float, str))}
                for o in bpy.data.objects if o.type == "EMPTY"}
print("RESULT " + json.dumps(out))
'''


def test_blender_keeps_groups_axes_and_units_of_a_y_up_centimetre_shot(blender_python, write_stage, tmp_path):
    """Without our schemas Blender must still see the groups (fallbackPrimTypes): agents stay under
    World/Crowd and land where usdcrowd put them, converted to Blender's Z-up metres."""
    from tests.helpers.frames import straight_walk
    from tests.helpers.shots import Y_UP_CM

    from usdcrowd.jobs.pipeline import author_shot
    from usdcrowd.scenario.crowd import read_crowd

    scenario = write_stage(Y_UP_CM, up="Y", mpu=0.01)
    shot = author_shot(scenario, tmp_path / "shot", lambda sc: [straight_walk(sc.agents, sc.time)],
                       progress=False, events=False).shot
    frames = [1, 6, 12]
    script = tmp_path / "hierarchy.py"
    script.write_text(HIERARCHY_SCRIPT)
    run = subprocess.run([blender_python, str(script), shot, ",".join(map(str, frames))], capture_output=True,
                         text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    got = json.loads(next(ln for ln in run.stdout.splitlines() if ln.startswith("RESULT "))[len("RESULT "):])
    assert got["chains"] and all(chain[1:3] == ["Crowd", "World"] for chain in got["chains"].values()), got["chains"]
    crowd, info = read_crowd(shot)
    heads = np.array(list(got["roots"].values()))[:, :, :2]                          # Blender: Z-up metres
    walked = np.swapaxes(crowd.position[np.array(frames) - 1][:, info.visible, :2], 0, 1)   # canonical metres
    gap = np.linalg.norm(heads[:, None] - walked[None], axis=-1).max(axis=2)
    match = gap.argmin(axis=1)
    assert len(set(match.tolist())) == len(heads) == len(walked)
    assert gap[np.arange(len(heads)), match].max() < 1e-4
    # Agent ids and group attributes arrive as custom properties (Blender's userProperties namespace).
    props = got["props"]
    agents = {p["crowd:agentId"]: p for p in props.values() if "crowd:agentId" in p}
    assert sorted(agents) == sorted(info.agent_id[info.visible].tolist())
    assert {p["crowd:group"] for p in agents.values()} == {"/World/Crowd"}
    assert props["Crowd"]["crowd:clones"] == 3 and props["Crowd"]["crowd:agents"] == len(info.agent_id)


TORIC_SCRIPT = '''
import bpy, json, sys
from bpy_extras.object_utils import world_to_camera_view
from mathutils import Vector
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.wm.usd_import(filepath=sys.argv[1])
heads = json.loads(open(sys.argv[2]).read())
scene = bpy.context.scene
scene.render.resolution_x, scene.render.resolution_y = 1920, 1080
cam = bpy.data.objects[sys.argv[3]]
out = {}
for f, hs in heads.items():
    scene.frame_set(int(f))
    out[f] = [list(world_to_camera_view(scene, cam, Vector(h)))[:2] for h in hs]
print("RESULT " + json.dumps(out))
'''


def test_blender_sees_the_two_heads_where_the_toric_camera_says(blender_python, tmp_path):
    """Blender's own projection, through the toric camera it imports, puts the heads at crowd:toric:pA and pB."""
    import shutil

    from usdcrowd.cameras.features import head_and_facing
    from usdcrowd.cli import main
    from usdcrowd.scenario.shot_scene import ShotScene
    from usdcrowd.core.resources import data_dir

    shutil.copy(data_dir("stages") / "dialogue.usda", tmp_path / "dialogue.usda")
    shot = tmp_path / "shot"
    assert main(["simulate", str(tmp_path / "dialogue.usda"), "-o", str(shot), "--frames", "1:120",
                 "--no-progress"]) == 0
    assert main(["frame", str(shot / "shot.usda"), "--behavior", "orbit", "--targets", "A", "B", "--shot",
                 "close-up", "--smooth", "--no-progress"]) == 0
    scene = ShotScene(shot / "shot.usda")
    rows = [scene.agent_row("A"), scene.agent_row("B")]
    frames = (1, 45, 90, 120)
    heads = {t: head_and_facing(scene.agents(t, rows).joints_world)[0].tolist() for t in frames}
    (tmp_path / "heads.json").write_text(json.dumps(heads))
    script = tmp_path / "toric.py"
    script.write_text(TORIC_SCRIPT)
    run = subprocess.run([blender_python, str(script), str(shot / "shot.usda"), str(tmp_path / "heads.json"),
                          "Orbit_A_B"], capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    got = json.loads(next(ln for ln in run.stdout.splitlines() if ln.startswith("RESULT "))[len("RESULT "):])
    prim = scene.stage.GetPrimAtPath("/World/Cameras/Orbit_A_B")
    for t in frames:
        blender_ndc = np.array(got[str(t)]) * 2 - 1
        authored = [prim.GetAttribute("crowd:toric:pA").Get(t), prim.GetAttribute("crowd:toric:pB").Get(t)]
        np.testing.assert_allclose(blender_ndc, np.array(authored, dtype=float), atol=1e-4)


DOME_SCRIPT = '''
import bpy, sys
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.context.scene.world = bpy.data.worlds.new("W")    # Blender makes the dome's world only into an existing one
bpy.ops.wm.usd_import(filepath=sys.argv[1], create_world_material=True)
sc = bpy.context.scene
sc.render.engine = "CYCLES"
sc.cycles.device = "CPU"
sc.cycles.samples = 16
sc.cycles.use_denoising = False
sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = 400, 200, 100
sc.view_settings.view_transform = "Standard"
sc.render.image_settings.file_format = "PNG"
for name in sys.argv[2:]:
    sc.camera = bpy.data.objects[name]
    sc.render.filepath = sys.argv[1] + "." + name + ".png"
    bpy.ops.render.render(write_still=True)
print("RESULT {}")
'''


def test_a_textured_dome_faces_the_same_way_in_blender_cycles(blender_python, tmp_path):
    """A lat-long sky with two marks on a Z-up stage: usdcrowd sees each where UsdLux says (DomeLight's pole on
    +Y, the OpenEXR lat-long convention) and where Blender Cycles, importing the same stage, sees it."""
    from PIL import Image

    from usdcrowd.render.final.frame import FrameRenderer

    w, h = 360, 180                                   # one texel a degree
    sky = np.full((h, w, 3), 20, np.uint8)
    sky[50:90, 90] = (0, 255, 0)                      # green: u = 90.5 / 360, latitudes 0 to 40 degrees
    sky[90:130, 270] = (255, 0, 0)                    # red: u = 270.5 / 360, latitudes 0 to -40 degrees
    Image.fromarray(sky).save(tmp_path / "sky.png")
    cams = "".join(f'''
    def Camera "Cam{k}"
    {{
        float focalLength = 1.8
        float horizontalAperture = 3.6
        float verticalAperture = 1.8
        float2 clippingRange = (0.1, 100)
        float3 xformOp:rotateXYZ = (90, 0, {yaw})
        uniform token[] xformOpOrder = ["xformOp:rotateXYZ"]
    }}''' for k, yaw in enumerate((90, 270)))
    stage = tmp_path / "dome.usda"
    stage.write_text(f'''#usda 1.0
(
    defaultPrim = "World"
    metersPerUnit = 1
    upAxis = "Z"
    startTimeCode = 1
    endTimeCode = 1
)
def Xform "World"
{{
    def DomeLight "Sky"
    {{
        asset inputs:texture:file = @./sky.png@
        float inputs:intensity = 1
    }}{cams}
}}
''')
    script = tmp_path / "dome.py"
    script.write_text(DOME_SCRIPT)
    run = subprocess.run([blender_python, str(script), str(stage), "Cam0", "Cam1"], capture_output=True, text=True,
                         timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]

    def directions(img, m):
        """Unit direction of each mark's centroid, through camera ``m`` (90 by 53 degrees, 400 x 200 px)."""
        out = {}
        for name, mask in (("red", (img[..., 0] > 0.4) & (img[..., 1] < 0.3)),
                           ("green", (img[..., 1] > 0.4) & (img[..., 0] < 0.3))):
            if mask.sum() < 20:
                continue
            rows, cols = np.argwhere(mask).T + 0.5
            d = -m[2, :3] + (cols.mean() - 200) / 200 * m[0, :3] - (rows.mean() - 100) / 200 * m[1, :3]
            out[name] = d / np.linalg.norm(d)
        return out

    def spec(u, lat_deg):
        """The OpenEXR lat-long direction (UsdLux DomeLight: pole +Y; longitude 0 at +Z, pi / 2 at +X)."""
        lon, lat = np.pi - 2 * np.pi * u, np.radians(lat_deg)
        return np.array([np.cos(lat) * np.sin(lon), np.sin(lat), np.cos(lat) * np.cos(lon)])

    expected = {"green": spec(90.5 / 360, 90 - 70), "red": spec(270.5 / 360, 90 - 110)}

    def angle(a, b):
        return float(np.degrees(np.arccos(np.clip(a @ b, -1, 1))))

    seen = set()
    for name in ("Cam0", "Cam1"):
        ours = FrameRenderer(stage, f"/World/{name}", (400, 200), spp=16, max_depth=1, ground_truth=False).render(1)
        theirs = np.asarray(Image.open(f"{stage}.{name}.png").convert("RGB")).astype(float) / 255
        a, b = directions(ours.beauty, ours.camera.cam_to_world), directions(theirs, ours.camera.cam_to_world)
        assert a.keys() == b.keys(), (a, b)
        for mark in a:
            assert angle(a[mark], b[mark]) < 1.0, (mark, a[mark], b[mark])       # Cycles agrees
            # And the spec: the same longitude, and latitude on the same side (a segment's projected
            # centroid leans toward its far end, so only the side is compared).
            lon = np.degrees(np.arctan2(a[mark][0], a[mark][2]) - np.arctan2(expected[mark][0], expected[mark][2]))
            assert abs((lon + 180) % 360 - 180) < 1.0, (mark, a[mark], expected[mark])
            assert np.sign(a[mark][1]) == np.sign(expected[mark][1]) and abs(a[mark][1]) > 0.2
            seen.add(mark)
    assert seen == {"red", "green"}


PALETTE_SCRIPT = '''
import bpy, json, sys
import numpy as np
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.wm.usd_import(filepath=sys.argv[1])
bodies = []
for o in bpy.data.objects:
    if o.type != "MESH" or not o.name.startswith("Body"):
        continue
    attr = o.data.color_attributes.get("displayColor")
    colors = np.array([tuple(d.color)[:3] for d in attr.data]) if attr is not None else None
    slots = []
    for slot in o.material_slots:
        tree = slot.material.node_tree
        bsdf = next(n for n in tree.nodes if n.type == "BSDF_PRINCIPLED")
        link = bsdf.inputs["Base Color"].links[0].from_node if bsdf.inputs["Base Color"].is_linked else None
        slots.append([slot.material.name, bsdf.inputs["Roughness"].default_value,
                      getattr(link, "attribute_name", None)])
    bodies.append({"domain": attr.domain if attr is not None else None,
                   "colors": colors.tolist() if colors is not None else None, "slots": slots})
print("RESULT " + json.dumps(bodies))
'''


def test_blender_dresses_each_agent_in_its_palette(blender_python, tmp_path):
    """Blender's importer gives every body its per-vertex palette colours and one material per region,
    each reading displayColor with the region's roughness."""
    from pxr import Usd, UsdGeom

    from usdcrowd.character import appearance
    from usdcrowd.character.body import REGIONS
    from usdcrowd.jobs.pipeline import simulate_shot
    from usdcrowd.core.resources import data_dir

    shot = simulate_shot(data_dir("stages") / "dialogue.usda", tmp_path / "shot", frames=(1, 4), progress=False).shot
    script = tmp_path / "palette.py"
    script.write_text(PALETTE_SCRIPT)
    run = subprocess.run([blender_python, str(script), str(shot)], capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    bodies = json.loads(next(ln for ln in run.stdout.splitlines() if ln.startswith("RESULT "))[len("RESULT "):])
    stage = Usd.Stage.Open(str(shot))
    ours = [np.array(UsdGeom.PrimvarsAPI(p).GetPrimvar("displayColor").ComputeFlattened(), dtype=float)
            for p in stage.Traverse() if p.GetName() == "Body" and p.IsA(UsdGeom.Mesh)]
    assert len(bodies) == len(ours) == 4
    unmatched = list(range(len(ours)))
    rough = dict(zip(REGIONS, appearance.roughness()))
    for body in bodies:
        assert body["domain"] == "POINT"
        colors = np.array(body["colors"])
        hit = [k for k in unmatched if ours[k].shape == colors.shape and np.allclose(ours[k], colors, atol=1e-6)]
        assert len(hit) == 1, "each Blender body wears exactly one agent's palette"
        unmatched.remove(hit[0])
        assert len(np.unique(colors.round(5), axis=0)) == len(REGIONS)
        assert sorted(name.split(".")[0] for name, _, _ in body["slots"]) == sorted(r.capitalize() for r in REGIONS)
        for name, roughness, attribute in body["slots"]:
            assert roughness == pytest.approx(rough[name.split(".")[0].lower()], abs=1e-6)
            assert attribute == "displayColor"


SUN_LEVEL_SCRIPT = '''
import bpy, json, sys
out = {}
for path in sys.argv[1:]:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.usd_import(filepath=path)
    sc = bpy.context.scene
    sc.render.engine = "CYCLES"
    sc.cycles.device = "CPU"
    sc.cycles.samples = 16
    sc.cycles.use_denoising = False
    sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = 32, 32, 100
    sc.view_settings.view_transform = "Standard"
    sc.camera = bpy.data.objects["Cam"]
    sc.render.image_settings.file_format = "OPEN_EXR"
    sc.render.filepath = path + ".exr"
    bpy.ops.render.render(write_still=True)
    sun = bpy.data.objects["Sun"].data
    out[path] = {"energy": sun.energy, "normalize": sun.normalize}
print("RESULT " + json.dumps(out))
'''


def test_blender_lights_the_ground_with_our_sun_as_usdlux_means_it(blender_python, tmp_path):
    """UsdLux: a DistantLight's intensity is its disc's luminance unless ``inputs:normalize`` makes it the
    illuminance. Our suns are normalised, so Blender Cycles lights the ground with them (4x brighter than
    usdcrowd: Blender's importer multiplies a sun's intensity by 4, "approximately matches Karma" says its
    source); the same sun unnormalised is all but dark in both renderers."""
    import OpenEXR

    from usdcrowd.render.final.frame import FrameRenderer

    stage = '''#usda 1.0
(
    defaultPrim = "World"
    metersPerUnit = 1
    upAxis = "Z"
    startTimeCode = 1
    endTimeCode = 1
)
def Xform "World"
{
    def Mesh "Ground"
    {
        int[] faceVertexCounts = [4]
        int[] faceVertexIndices = [0, 1, 2, 3]
        point3f[] points = [(-20, -20, 0), (20, -20, 0), (20, 20, 0), (-20, 20, 0)]
        color3f[] primvars:displayColor = [(0.8, 0.8, 0.8)]
    }
    def DistantLight "Sun"
    {
        bool inputs:normalize = NORMALIZE
        float inputs:intensity = 3
        float3 xformOp:rotateXYZ = (0, -45, 0)
        uniform token[] xformOpOrder = ["xformOp:rotateXYZ"]
    }
    def Camera "Cam"
    {
        float focalLength = 18
        float horizontalAperture = 36
        float verticalAperture = 36
        double3 xformOp:translate = (0, 0, 5)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }
}
'''
    paths = []
    for normalize in ("true", "false"):
        paths.append(tmp_path / f"sun_{normalize}.usda")
        paths[-1].write_text(stage.replace("NORMALIZE", normalize))
    script = tmp_path / "sun.py"
    script.write_text(SUN_LEVEL_SCRIPT)
    run = subprocess.run([blender_python, str(script), *map(str, paths)], capture_output=True, text=True,
                         timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    got = json.loads(next(ln for ln in run.stdout.splitlines() if ln.startswith("RESULT "))[len("RESULT "):])

    def theirs(path):
        with OpenEXR.File(f"{path}.exr") as f:
            ch = f.channels()
            rgb = ch["RGBA"].pixels if "RGBA" in ch else ch["RGB"].pixels
        return float(np.median(np.asarray(rgb, dtype=np.float64)[..., 1]))

    ours = [float(np.median(FrameRenderer(p, "/World/Cam", (32, 32), spp=16, max_depth=2, ground_truth=False)
                            .render(1).beauty[..., 1])) for p in paths]
    cycles = [theirs(p) for p in paths]
    assert got[str(paths[0])]["normalize"] and not got[str(paths[1])]["normalize"]
    assert ours[0] > 0.2                                       # a grey ground under a sun of illuminance 3
    print(f"sun-lit ground: Cycles {cycles}, usdcrowd {ours}")
    assert 3.4 < cycles[0] / ours[0] < 4.8, (cycles, ours)
    assert ours[1] / ours[0] < 1e-3 and cycles[1] / cycles[0] < 1e-3, (cycles, ours)
