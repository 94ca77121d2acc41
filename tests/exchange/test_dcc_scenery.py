"""A DCC tool's scenery under a template crowd: Blender builds a small town in two conventions."""

from __future__ import annotations

import subprocess
import textwrap

import numpy as np
import pytest

from usdcrowd.cli import main

# Built by Blender: a 60 m ground plane, a 4 x 6 x 5 m hall at (14, 9), a 3 x 3 x 12 m tower at (-15, -12)
# turned 30 degrees, a sun and a 35 mm camera.
TOWN_SCRIPT = '''
import bpy, math, sys
out, up, units = sys.argv[1], sys.argv[2], sys.argv[3]
bpy.ops.wm.read_factory_settings(use_empty=True)
def box(name, x, y, sx, sy, sz, turn=0.0):
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(x, y, sz / 2))
    o = bpy.context.active_object
    o.name, o.scale, o.rotation_euler = name, (sx, sy, sz), (0, 0, math.radians(turn))
bpy.ops.mesh.primitive_plane_add(size=60.0, location=(0, 0, 0))
box("Hall", 14.0, 9.0, 4.0, 6.0, 5.0)
box("Tower", -15.0, -12.0, 3.0, 3.0, 12.0, 30.0)
sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
bpy.context.scene.collection.objects.link(sun)
cam = bpy.data.cameras.new("TownCam")
cam.lens, cam.sensor_width = 35.0, 36.0
co = bpy.data.objects.new("TownCam", cam)
bpy.context.scene.collection.objects.link(co)
co.location, co.rotation_euler = (0, -40, 12), (math.radians(75), 0, 0)
kw = dict(convert_orientation=True, export_global_up_selection="Y",
          export_global_forward_selection="NEGATIVE_Z") if up == "Y" else {}
bpy.ops.wm.usd_export(filepath=out, convert_scene_units=units, **kw)
'''
HALL = (12.0, 6.0, 16.0, 12.0)      # footprint x0, y0, x1, y1, metres


def _dcc_box(path, root: str, up: str, mpu: float, size: float, translate, scale=(1, 1, 1)):
    """A DCC-style layer: one root Xform holding a Cube, in ``up`` axis and ``mpu`` metres per unit."""
    path.write_text(textwrap.dedent(f'''\
        #usda 1.0
        (
            defaultPrim = "{root}"
            metersPerUnit = {mpu}
            upAxis = "{up}"
        )
        def Xform "{root}"
        {{
            def Cube "Box"
            {{
                double size = {size}
                double3 xformOp:translate = {tuple(translate)}
                float3 xformOp:scale = {tuple(scale)}
                uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:scale"]
            }}
        }}
        '''))


@pytest.fixture(scope="module")
def towns(tmp_path_factory):
    """The town exported by Blender as Z-up metres and as Y-up centimetres, each under the museum crowd."""
    from tests.helpers.venvs import BPY, tool_python

    python = tool_python("bpy", BPY, "USDCROWD_BPY_VENV")
    tmp = tmp_path_factory.mktemp("towns")
    script = tmp / "town.py"
    script.write_text(TOWN_SCRIPT)
    out = {}
    for name, up, units in (("z_m", "Z", "METERS"), ("y_cm", "Y", "CENTIMETERS")):
        town = tmp / f"town_{name}.usda"
        run = subprocess.run([python, str(script), str(town), up, units], capture_output=True, text=True,
                             timeout=600)
        assert run.returncode == 0, run.stderr[-2000:]
        scenario = tmp / f"scenario_{name}.usda"
        assert main(["new", "museum", "-o", str(scenario), "--agents", "30", "--scenery", str(town)]) == 0
        out[name] = (town, scenario)
    return out


@pytest.mark.slow
def test_a_blender_town_in_either_convention_becomes_the_same_obstacles(towns):
    from usdcrowd.scenario import load_scenario

    found = {}
    for name, (town, scenario) in towns.items():
        assert "upAxis = \"Y\"" in town.read_text() if name == "y_cm" else "metersPerUnit = 1" in town.read_text()
        obstacles = load_scenario(scenario).obstacles
        found[name] = {p.rsplit("/", 2)[-2]: (poly, h) for p, poly, h in
                       zip(obstacles.path, obstacles.polygons, obstacles.height)}
        assert set(found[name]) == {"Hall", "Tower"}         # the ground is ground, not an obstacle
        hall, height = found[name]["Hall"]
        np.testing.assert_allclose([*hall.min(0), *hall.max(0)], HALL, atol=1e-4)
        assert height == pytest.approx(5.0, abs=1e-4)
        tower, height = found[name]["Tower"]
        assert height == pytest.approx(12.0, abs=1e-4)
        np.testing.assert_allclose(tower.mean(0), (-15.0, -12.0), atol=1e-3)
        # Turned 30 degrees: its corners reach 1.5 (cos 30 + sin 30) = 2.05 m from the centre along x.
        assert tower[:, 0].max() - tower[:, 0].min() == pytest.approx(3.0 * (np.cos(np.pi / 6) + 0.5), abs=1e-3)
    for key in ("Hall", "Tower"):
        np.testing.assert_allclose(np.sort(found["y_cm"][key][0], axis=0), np.sort(found["z_m"][key][0], axis=0),
                                   atol=1e-4)


@pytest.mark.slow
def test_the_towns_lights_and_camera_are_the_shots(towns):
    from pxr import Usd, UsdLux

    from usdcrowd.scenario.shot_scene import ShotScene

    for name, (_, scenario) in towns.items():
        stage = Usd.Stage.Open(str(scenario))
        lights = [str(p.GetPath()) for p in stage.Traverse() if p.HasAPI(UsdLux.LightAPI)]
        assert lights == ["/World/Scenery/root/Sun/Sun"], (name, lights)
        scene = ShotScene(scenario)
        cam = scene.camera("/World/Scenery/root/TownCam/TownCam", 1)
        # 35 mm whatever the file's units (tenths of *its* scene unit), at (0, -40, 12) m.
        assert cam.focal_length == pytest.approx(35.0, rel=1e-6) and cam.horizontal_aperture == pytest.approx(36.0)
        # Blender's default clipping, 0.1 to 1,000 m, also in the file's units.
        assert (cam.near, cam.far) == (pytest.approx(0.1, rel=1e-6), pytest.approx(1000.0, rel=1e-6))
        np.testing.assert_allclose(cam.cam_to_world[3, :3], (0.0, -40.0, 12.0), atol=1e-5)
        assert len(scene.scenery) >= 3            # ground, hall and tower are drawn


def test_validate_reports_a_reference_in_other_units_without_its_correction(write_stage, tmp_path, capsys):
    town = tmp_path / "town.usda"
    town.write_text(textwrap.dedent('''\
        #usda 1.0
        (
            defaultPrim = "Town"
            metersPerUnit = 0.01
            upAxis = "Y"
        )
        def Xform "Town"
        {
            def Cube "Hall"
            {
                double size = 500
            }
        }
        '''))
    bare = write_stage('''
def Xform "World"
{
    def Xform "Scenery"
    {
        def "Town" (prepend references = @./town.usda@)
        {
        }
    }
}
''')
    assert main(["validate", str(bare)]) == 1
    out = capsys.readouterr().out
    assert "/World/Scenery/Town" in out and "Y-up centimetres" in out and "Z-up metres" in out
    placed = tmp_path / "placed.usda"
    assert main(["new", "dialogue", "-o", str(placed), "--scenery", str(town)]) == 0
    capsys.readouterr()
    main(["validate", str(placed)])
    assert "town.usda" not in capsys.readouterr().out


def test_instanced_scenery_with_any_transform_ops_blocks_walking_and_is_drawn(write_stage, tmp_path):
    """Instanceable references (instance proxies) under translate, rotateXYZ, orient, scale and matrix ops."""
    from usdcrowd.scenario.shot_scene import ShotScene
    from usdcrowd.scenario import load_scenario

    _dcc_box(tmp_path / "kiosk.usda", "Kiosk", "Z", 1, 2, (0, 0, 1))
    stage = write_stage('''
def Xform "World"
{
    def "A" (instanceable = true
        prepend references = @./kiosk.usda@)
    {
        double3 xformOp:translate = (10, 0, 0)
        float3 xformOp:rotateXYZ = (0, 0, 45)
        uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateXYZ"]
    }
    def "B" (instanceable = true
        prepend references = @./kiosk.usda@)
    {
        quatf xformOp:orient = (0.70710677, 0, 0, 0.70710677)
        float3 xformOp:scale = (2, 1, 1)
        matrix4d xformOp:transform = ( (1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (-10, 5, 0, 1) )
        uniform token[] xformOpOrder = ["xformOp:transform", "xformOp:orient", "xformOp:scale"]
    }
    def CrowdGroup "Crowd"
    {
        uniform int crowd:clones = 2
    }
}
''', name="world.usda")
    assert stage.parent == tmp_path           # beside the kiosk it references
    obstacles = load_scenario(stage).obstacles
    boxes = {p.split("/")[2]: poly for p, poly in zip(obstacles.path, obstacles.polygons)}
    assert set(boxes) == {"A", "B"}
    # A: a 2 m box turned 45 degrees at (10, 0): its corners sqrt(2) m away along the axes.
    np.testing.assert_allclose([boxes["A"][:, 0].min(), boxes["A"][:, 0].max()], [10 - 2 ** 0.5, 10 + 2 ** 0.5],
                               atol=1e-5)
    # B: stretched to 4 m along its x, then turned 90 degrees: 2 m wide in x, 4 m long in y, at (-10, 5).
    np.testing.assert_allclose([*boxes["B"].min(0), *boxes["B"].max(0)], [-11, 3, -9, 7], atol=1e-5)
    assert len(ShotScene(stage).scenery) == 2


@pytest.mark.slow
def test_the_town_is_rendered_through_its_own_camera_and_lit_by_its_sun(towns, tmp_path):
    pytest.importorskip("mitsuba")
    from usdcrowd.render.final.frame import FrameRenderer
    from usdcrowd.scenario.shot_scene import ShotScene

    _, scenario = towns["y_cm"]
    shot = tmp_path / "shot"
    assert main(["simulate", str(scenario), "-o", str(shot), "--frames", "1:2", "--no-progress"]) == 0
    assert [light.path for light in ShotScene(shot / "shot.usda").lights] == ["/World/Scenery/root/Sun/Sun"]
    cam = "/World/Scenery/root/TownCam/TownCam"
    buildings = {"/World/Scenery/root/Hall/Cube", "/World/Scenery/root/Tower/Cube_001"}
    r = FrameRenderer(shot / "shot.usda", cam, (96, 54), spp=2).render(1)
    assert buildings <= {r.id_paths.get(int(i)) for i in np.unique(r.gt.ids)}
    assert r.beauty.mean() > 0.01             # lit by the town's sun
    # The OpenGL preview draws it too, through the same camera.
    pytest.importorskip("moderngl")
    from usdcrowd.core.errors import UsdcrowdError
    from usdcrowd.render.preview import PreviewRenderer

    try:
        preview = PreviewRenderer(shot / "shot.usda", 160, 90)
    except UsdcrowdError as exc:
        pytest.skip(str(exc))
    try:
        frame = preview.render(1, cam)
    finally:
        preview.release()
    shape_paths = {item.shape_id: item.path for item in ShotScene(shot / "shot.usda").scenery}
    assert buildings <= {shape_paths.get(int(i)) for i in np.unique(frame.ids)}


def test_walkers_go_around_a_centimetre_y_up_wall_in_their_way(write_stage, tmp_path):
    """A 12 m wide, 3 m tall wall from a Y-up centimetre file, referenced with its correction, stands
    between a group and its goal: nobody walks through it, and in 15 s most have gone round it (walking
    in file round its ends, keeping their time gap to the one ahead)."""
    from usdcrowd.scenario import load_scenario
    from usdcrowd.scenario.crowd import read_crowd

    _dcc_box(tmp_path / "wall.usda", "Wall", "Y", 0.01, 100, (0, 150, 0), (1, 3, 12))
    # The correction usdcrowd new --scenery authors: Y-up to Z-up, centimetres to metres.
    fix = ('float xformOp:rotateX = 90\n        float3 xformOp:scale = (0.01, 0.01, 0.01)\n'
           '        uniform token[] xformOpOrder = ["xformOp:rotateX", "xformOp:scale"]')
    scenario = write_stage(f'''
def Xform "World"
{{
    def Xform "Scenery"
    {{
        {fix}
        def "Wall" (prepend references = @./wall.usda@)
        {{
        }}
    }}
    def CrowdGroup "Walkers"
    {{
        uniform int crowd:clones = 12
        uniform token crowd:behavior = "walk"
        uniform point3f crowd:spawnCenter = (-6, 0, 0)
        uniform float crowd:spawnRadius = 2
        uniform point3f crowd:goal = (8, 0, 0)
    }}
}}
''', end=360)
    (wall,) = load_scenario(scenario).obstacles.polygons
    # Blender's/any DCC's wall: 1 m thick (x), 12 m wide (y: the file's -z), 3 m tall, at the origin.
    np.testing.assert_allclose([*wall.min(0), *wall.max(0)], [-0.5, -6, 0.5, 6], atol=1e-6)
    shot = tmp_path / "shot"
    assert main(["simulate", str(scenario), "-o", str(shot), "--no-progress"]) == 0
    frames, _ = read_crowd(shot / "shot.usda")
    x, y = frames.position[..., 0], frames.position[..., 1]
    assert not ((np.abs(x) < 0.45) & (np.abs(y) < 5.95)).any()          # never inside the wall
    assert (x[-1] > 0.6).mean() > 0.5                                       # most got past it, around it


def _box_mesh(name: str, centre, size, reverse: bool = False) -> str:
    """A box as a Mesh prim in world coordinates (usda text); ``reverse`` lists its points the other way
    round (the faces follow), as another exporter may."""
    corners = np.array([[x, y, z] for z in (0, 1) for y in (-0.5, 0.5) for x in (-0.5, 0.5)])
    points = np.asarray(centre, dtype=float) + corners * np.asarray(size, dtype=float)
    quads = np.array([[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]])
    if reverse:
        points, quads = points[::-1], 7 - quads
    return (f'def Mesh "{name}"\n{{\n    int[] faceVertexCounts = {[4] * 6}\n'
            f'    int[] faceVertexIndices = {quads.ravel().tolist()}\n'
            f'    point3f[] points = [{", ".join(str(tuple(p.tolist())) for p in points)}]\n}}\n')


def _town_layer(path, roots: dict, default: str | None = None) -> None:
    """A Z-up metre layer with ``roots`` ({root name: [box mesh usda, ...]}) and optionally a defaultPrim."""
    head = f'    defaultPrim = "{default}"\n' if default else ""
    body = "".join(f'def Xform "{root}"\n{{\n{textwrap.indent("".join(boxes), "    ")}}}\n'
                   for root, boxes in roots.items())
    path.write_text(f'#usda 1.0\n(\n{head}    metersPerUnit = 1\n    upAxis = "Z"\n)\n{body}')


def test_a_scenery_without_default_prim_brings_every_root_prim(tmp_path, capsys):
    """Two root prims and no defaultPrim: the kiosk beside the town blocks walking and is drawn too."""
    from pxr import Usd

    from usdcrowd.scenario.shot_scene import ShotScene
    from usdcrowd.scenario import load_scenario
    from usdcrowd.scenario.scenery import dropped_root_problems

    town = tmp_path / "town.usda"
    _town_layer(town, {"Town": [_box_mesh("Hall", (14, 9, 0), (4, 6, 5))],
                       "Kiosk": [_box_mesh("Booth", (-6, -3, 0), (2, 1, 2.5))]})
    scenario = tmp_path / "scenario.usda"
    assert main(["new", "dialogue", "-o", str(scenario), "--scenery", str(town)]) == 0
    assert "scenery" in capsys.readouterr().out
    obstacles = load_scenario(scenario).obstacles
    found = {p: (poly, h) for p, poly, h in zip(obstacles.path, obstacles.polygons, obstacles.height)}
    assert set(found) == {"/World/Scenery/Town/Hall", "/World/Scenery/Kiosk/Booth"}
    booth, height = found["/World/Scenery/Kiosk/Booth"]
    np.testing.assert_allclose([*booth.min(0), *booth.max(0)], [-7, -3.5, -5, -2.5], atol=1e-6)
    assert height == pytest.approx(2.5)
    hall, _ = found["/World/Scenery/Town/Hall"]
    np.testing.assert_allclose([*hall.min(0), *hall.max(0)], HALL, atol=1e-6)
    drawn = {item.path: item for item in ShotScene(scenario).scenery}
    assert {"/World/Scenery/Town/Hall", "/World/Scenery/Kiosk/Booth"} <= set(drawn)
    world = drawn["/World/Scenery/Kiosk/Booth"].local_to_world(1)
    points = drawn["/World/Scenery/Kiosk/Booth"].mesh.vertices @ world[:3, :3] + world[3, :3]
    np.testing.assert_allclose([*points.min(0), *points.max(0)], [-7, -3.5, 0, -5, -2.5, 2.5], atol=1e-6)
    assert dropped_root_problems(Usd.Stage.Open(str(scenario))) == []


def test_validate_reports_a_reference_that_drops_root_prims(write_stage, tmp_path):
    """A hand-written scenario naming one root of a file without defaultPrim loses the other: reported."""
    from pxr import Usd

    from usdcrowd.scenario.scenery import dropped_root_problems

    _town_layer(tmp_path / "town.usda", {"Town": [_box_mesh("Hall", (14, 9, 0), (4, 6, 5))],
                                         "Kiosk": [_box_mesh("Booth", (-6, -3, 0), (2, 1, 2.5))]})
    _town_layer(tmp_path / "kept.usda", {"Town": [_box_mesh("Hall", (14, 9, 0), (4, 6, 5))],
                                         "Kiosk": [_box_mesh("Booth", (-6, -3, 0), (2, 1, 2.5))]}, default="Town")
    stage = write_stage('''
def Xform "World"
{
    def Xform "Scenery"
    {
        def "Town" (prepend references = @./town.usda@</Town>)
        {
        }
        def "Declared" (prepend references = @./kept.usda@)
        {
        }
    }
}
''')
    (problem,) = dropped_root_problems(Usd.Stage.Open(str(stage)))
    file, prim, message = problem
    assert (file, prim) == (str(stage), "/World/Scenery/Town")
    assert "/Kiosk" in message and "/Town" not in message.split("root prim(s)")[1] and "\n" not in message


# Boxes that overlap on the museum students' spawn disc ((-11, 6), 2 m) and the family's ((-12, -6), 1.5 m):
# agents spawned inside are pushed out of whichever footprint owns the overlap.
ORDER_TOWN = [((-11, 6, 0), (1.2, 3.5, 3)), ((-11, 6.2, 0), (3.5, 1.2, 2)), ((-12, -6, 0), (1.5, 3, 2)),
              ((-12, -6, 0), (3, 1.5, 3)), ((-9.5, 0.5, 0), (1, 2, 4)), ((-9.7, 1, 0), (2, 0.6, 1.2))]


def test_the_same_town_with_its_prims_in_another_order_gives_the_same_crowd(tmp_path):
    """Another exporter writes the same boxes in another order, under other names, their points the other
    way round: the obstacles and the crowd (same seed) are the same, to a micrometre."""
    from usdcrowd.scenario import load_scenario
    from usdcrowd.scenario.crowd import read_crowd

    ground = ('def Mesh "Ground"\n{\n    int[] faceVertexCounts = [4]\n    int[] faceVertexIndices = [0, 1, 2, 3]\n'
              '    point3f[] points = [(-20, -15, 0), (20, -15, 0), (20, 15, 0), (-20, 15, 0)]\n}\n')
    order = [3, 1, 5, 0, 2, 4]
    towns = {"named": [ground] + [_box_mesh(f"Box{k}", *ORDER_TOWN[k]) for k in range(len(ORDER_TOWN))],
             "exported": [_box_mesh(f"Mesh_{i:03d}", *ORDER_TOWN[k], reverse=True) for i, k in enumerate(order)]
             + [ground]}
    crowds, obstacles = {}, {}
    for name, prims in towns.items():
        _town_layer(tmp_path / f"{name}.usda", {"root": prims}, default="root")
        scenario, shot = tmp_path / f"scenario_{name}.usda", tmp_path / f"shot_{name}"
        assert main(["new", "museum", "-o", str(scenario), "--agents", "40", "--seed", "5",
                     "--scenery", str(tmp_path / f"{name}.usda")]) == 0
        obstacles[name] = load_scenario(scenario).obstacles
        assert main(["simulate", str(scenario), "-o", str(shot), "--frames", "1:96", "--no-progress"]) == 0
        crowds[name] = read_crowd(shot / "shot.usda")[0].position
    a, b = obstacles["named"], obstacles["exported"]
    assert len(a) == len(b) == len(ORDER_TOWN)
    assert {p.rsplit("/", 1)[1] for p in a.path}.isdisjoint(p.rsplit("/", 1)[1] for p in b.path)
    for pa, pb in zip(a.polygons, b.polygons):
        np.testing.assert_array_equal(pa, pb)            # same footprints, same first vertex, same order
    np.testing.assert_array_equal(a.height, b.height)
    assert crowds["named"].shape == (96, 40, 3)
    np.testing.assert_allclose(crowds["exported"], crowds["named"], rtol=0, atol=1e-6)
