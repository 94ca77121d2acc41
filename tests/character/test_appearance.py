"""Per-agent palettes: drawn from the seed, written as USD means them, worn in both renderers."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from usdcrowd.character import appearance
from usdcrowd.character.body import REGIONS
from usdcrowd.jobs.pipeline import simulate_shot
from usdcrowd.core.resources import data_dir

# Strong, distinct colours an agent is dressed in by the stage that wraps the shot.
MARKED = {"top": (0.8, 0.05, 0.05), "trousers": (0.05, 0.05, 0.8), "skin": (0.5, 0.35, 0.25),
          "hair": (0.05, 0.6, 0.05), "shoes": (0.8, 0.8, 0.05), "eye_whites": (0.05, 0.6, 0.6),
          "face": (0.6, 0.05, 0.6)}
MARKED_AGENT = "/World/Crowd/Pair/A"
FRAME = 5.0


def _museum_palettes(seed: int):
    from usdcrowd.scenario.read import load_scenario

    return load_scenario(data_dir("stages") / "museum.usda", seed=seed)


def _rows(agents, group_suffix: str):
    return [i for i, p in enumerate(agents.path) if p.rsplit("/", 2)[-2] == group_suffix]


def test_palettes_are_drawn_from_the_seed_and_cover_every_region():
    a, b, c = (_museum_palettes(s).agents for s in (3, 3, 4))
    assert a.palette.shape == (len(a), len(REGIONS), 3)
    assert np.array_equal(a.palette, b.palette)
    assert not np.allclose(a.palette, c.palette)
    assert a.palette.min() >= 0 and a.palette.max() <= 1
    skin = a.palette[:, REGIONS.index("skin")]
    # Skin rows are Monk-scale swatches scaled to an albedo, brightened or darkened by the jitter only.
    table = appearance.SKIN_ALBEDO * appearance.srgb_to_linear(appearance._SKIN)
    ratio = skin[:, None, :] / table[None]
    nearest = np.abs(np.log(ratio) - np.log(ratio).mean(-1, keepdims=True)).max(-1).min(1)
    assert nearest.max() < 1e-6
    # A crowd: many distinct palettes, several skin tones and hair colours.
    # (the museum's Students come in four pairs of subclones, which dress alike).
    assert len(np.unique(a.palette.round(4), axis=0)) == len(a) - 4
    assert len(np.unique(np.argmin(np.abs(ratio - 1).sum(-1), 1))) >= 5


def test_an_authored_group_colour_tints_the_tops_but_keeps_them_apart():
    """The museum's Students author a group colour: their tops lean to it, yet differ from one another."""
    a = _museum_palettes(3).agents
    students = _rows(a, "Students")
    top = a.palette[students, REGIONS.index("top")]
    color = a.color[students]
    assert len(students) == 9
    # top = (1 - w) drawn + w colour, drawn in the unit cube: within (1 - w) sqrt(3) of the colour.
    assert np.linalg.norm(top - color, axis=1).max() <= (1 - appearance.GROUP_TINT) * np.sqrt(3) + 1e-9
    assert len(np.unique(top.round(4), axis=0)) > 2
    # Agents of groups with no colour of their own are not pulled anywhere: their tops spread out.
    solo = a.palette[_rows(a, "Solo"), REGIONS.index("top")]
    assert np.linalg.norm(solo - solo.mean(0), axis=1).max() > (1 - appearance.GROUP_TINT) * 0.5


def test_subclones_dress_alike():
    """Students clone in runs of two subclones, which share every drawn attribute, clothes included."""
    a = _museum_palettes(5).agents
    clones = [i for i in _rows(a, "Students") if "clone_" in a.path[i]]
    assert len(clones) == 8
    pal = a.palette[clones]
    for k in range(0, 8, 2):
        assert np.array_equal(pal[k], pal[k + 1])
    assert len({pal[k].tobytes() for k in range(0, 8, 2)}) == 4


@pytest.fixture(scope="module")
def dialogue_shot(tmp_path_factory):
    out = tmp_path_factory.mktemp("palettes")
    return simulate_shot(data_dir("stages") / "dialogue.usda", out / "shot", frames=(1, 8), progress=False).shot


PLAIN_USD = textwrap.dedent('''
    import json, sys
    import numpy as np
    from pxr import Usd, UsdGeom, UsdShade
    stage = Usd.Stage.Open(sys.argv[1])
    out = {}
    for prim in stage.Traverse():
        if prim.GetName() != "Body" or not prim.IsA(UsdGeom.Mesh):
            continue
        mesh = UsdGeom.Mesh(prim)
        pv = UsdGeom.PrimvarsAPI(prim).GetPrimvar("displayColor")
        colors = np.array(pv.ComputeFlattened(), dtype=float)
        faces = np.array(mesh.GetFaceVertexIndicesAttr().Get()).reshape(-1, 3)
        rough = np.full(len(faces), np.nan)
        names = [""] * len(faces)
        for subset in UsdGeom.Subset.GetGeomSubsets(mesh, "face", "materialBind"):
            mat = UsdShade.MaterialBindingAPI(subset.GetPrim()).ComputeBoundMaterial()[0]
            shader = mat.ComputeSurfaceSource()[0]
            reader = shader.GetInput("diffuseColor").GetConnectedSource()[0].GetPrim()
            idx = np.array(subset.GetIndicesAttr().Get())
            rough[idx] = shader.GetInput("roughness").Get()
            for i in idx:
                names[i] = reader.GetAttribute("inputs:varname").Get()
        ok, why = UsdGeom.Subset.ValidateFamily(mesh, "face", "materialBind")
        out[str(prim.GetPath().GetParentPath())] = {
            "interpolation": pv.GetInterpolation(), "colors": colors.tolist(), "face_roughness": rough.tolist(),
            "reads": sorted(set(names)), "partition": ok,
            "points": np.array(mesh.GetPointsAttr().Get()).tolist(), "faces": faces.tolist()}
    print(json.dumps(out))
''')


def test_plain_usd_sees_each_vertex_in_its_regions_colour_and_material(dialogue_shot, tmp_path):
    """usd-core without usdcrowd: the flattened displayColor and the subsets' materials are the palette's."""
    from usdcrowd.scenario.shot_scene import ShotScene

    script = tmp_path / "plain.py"
    script.write_text(PLAIN_USD)
    done = subprocess.run([sys.executable, "-I", str(script), str(dialogue_shot)], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    seen = json.loads(done.stdout)
    scene = ShotScene(dialogue_shot)
    palettes = scene.agents(FRAME).palette
    assert len(seen) == len(scene.agent_paths)
    rough = appearance.roughness()
    for row, path in enumerate(scene.agent_paths):
        body = seen[path]
        assert body["interpolation"] == "vertex" and body["partition"] and body["reads"] == ["displayColor"]
        colors, points = np.array(body["colors"]), np.array(body["points"])
        # Geometry tells the regions apart, independently of our index table:
        crown = np.argmax(points[:, 2])                       # top of the head: hair
        toe = np.argmax(np.where(points[:, 2] < 0.05, points[:, 0], -np.inf))   # front of a foot: shoe
        # A leg (at hip height, next to the body's midline, under the torso): trousers.
        knee = np.argmin(np.abs(points[:, 2] - 0.5) + 10 * (np.abs(points[:, 1]) > 0.2) + 10 * (points[:, 2] > 0.8))
        chest = np.argmax(np.where(np.abs(points[:, 2] - 1.3) < 0.05, points[:, 0], -np.inf))   # torso front: top
        nose = np.argmax(np.where(points[:, 2] > 1.5, points[:, 0], -np.inf))   # the nose: skin
        # Front-most at a left eye's place (3 cm above the nose's tip, 3.3 cm aside): the face's dark row.
        at_eye = (np.abs(points[:, 2] - (points[nose, 2] + 0.03)) < 0.01) & (np.abs(points[:, 1] - 0.033) < 0.01)
        eye = np.argmax(np.where(at_eye, points[:, 0], -np.inf))
        for vertex, region in ((crown, "hair"), (toe, "shoes"), (knee, "trousers"), (chest, "top"), (nose, "skin"),
                               (eye, "face")):
            k = REGIONS.index(region)
            assert np.allclose(colors[vertex], palettes[row, k], atol=1e-6), (path, region)
            face = next(i for i, f in enumerate(body["faces"]) if vertex in f and
                        all(np.allclose(colors[v], colors[vertex]) for v in f))
            assert body["face_roughness"][face] == pytest.approx(rough[k]), (path, region)


def _over_body(shot, agent: str, display_color: str) -> str:
    """A stage over ``shot`` that overrides one agent's body displayColor (as a user would)."""
    names = agent.strip("/").split("/")
    opening = "\n".join(f'over "{n}" {{' for n in names + ["Body"])
    closing = "}\n" * (len(names) + 1)
    from pxr import Sdf

    base = Sdf.Layer.FindOrOpen(str(shot))
    meta = ('    defaultPrim = "World"\n'
            f"    startTimeCode = {base.startTimeCode}\n    endTimeCode = {base.endTimeCode}\n"
            f"    timeCodesPerSecond = {base.timeCodesPerSecond}\n    framesPerSecond = {base.framesPerSecond}\n"
            f'    upAxis = "{base.pseudoRoot.GetInfo("upAxis")}"\n    metersPerUnit = {base.pseudoRoot.GetInfo("metersPerUnit")}\n')
    return f"#usda 1.0\n(\n{meta}    subLayers = [@{shot}@]\n)\n{opening}\n{display_color}\n{closing}"


def _marked_stage(shot, tmp_path) -> str:
    """A stage over the shot that dresses agent A in MARKED colours (as a user would override them)."""
    values = ", ".join(f"({r}, {g}, {b})" for r, g, b in (MARKED[k] for k in REGIONS))
    path = tmp_path / "marked.usda"
    path.write_text(_over_body(shot, MARKED_AGENT,
                               f'color3f[] primvars:displayColor = [{values}] (interpolation = "vertex")'))
    return str(path)


def test_final_frames_wear_the_palette_and_keep_the_ground_truth(dialogue_shot, tmp_path):
    pytest.importorskip("mitsuba")
    from usdcrowd.render.demo import final_outputs
    from usdcrowd.render.final.exr import read_frame_exr
    from usdcrowd.scenario.shot_scene import ShotScene

    marked = _marked_stage(dialogue_shot, tmp_path)
    outs = {}
    for name, stage in (("plain", str(dialogue_shot)), ("marked", marked)):
        final_outputs(stage, tmp_path / name, frames=(FRAME,), resolution=(320, 180), spp=4)
        _, ch = read_frame_exr(tmp_path / name / "exr" / f"frame.{int(FRAME):04d}.exr")
        outs[name] = ch
    # Ground truth does not depend on clothes.
    for k in ("id", "depth.z", "depth.distance", "normal.X", "position.Z"):
        assert np.array_equal(outs["plain"][k], outs["marked"][k]), k
    assert not np.array_equal(outs["plain"]["albedo.R"], outs["marked"]["albedo.R"])
    ch = outs["marked"]
    ids = ch["id"].astype(np.int64)
    agent_id = int(ShotScene(marked).agents(FRAME, None).agent_ids[ShotScene(marked).agent_row(MARKED_AGENT)])
    mine = ids == agent_id
    assert mine.sum() > 300, "the camera must see agent A"
    albedo = np.stack([ch["albedo.R"], ch["albedo.G"], ch["albedo.B"]], -1)[mine]
    table = np.array([MARKED[k] for k in REGIONS])
    dist = np.linalg.norm(albedo[:, None] - table[None], axis=-1)
    nearest, how_far = np.argmin(dist, 1), dist.min(1)
    # Most pixels are exactly one of the marked colours (the rest straddle a hairline or a seam).
    assert (how_far < 0.02).mean() > 0.8
    share = np.bincount(nearest[how_far < 0.02], minlength=len(REGIONS)) / mine.sum()
    for region in ("top", "trousers", "skin", "hair"):
        assert share[REGIONS.index(region)] > 0.01, (region, share)
    # Head above torso above legs, in the image.
    rows = np.nonzero(mine)[0]
    mean_row = {r: rows[(nearest == REGIONS.index(r)) & (how_far < 0.02)].mean() for r in ("hair", "top", "trousers")}
    assert mean_row["hair"] < mean_row["top"] < mean_row["trousers"]


def test_the_preview_wears_the_palette_too(dialogue_shot, tmp_path):
    pytest.importorskip("moderngl")
    from usdcrowd.core.errors import UsdcrowdError
    from usdcrowd.render.preview import LodSettings, PreviewRenderer
    from usdcrowd.scenario.shot_scene import ShotScene

    scene = ShotScene(_marked_stage(dialogue_shot, tmp_path))
    try:
        r = PreviewRenderer(scene, 320, 180, lod_settings=LodSettings(enabled=False))
    except UsdcrowdError as exc:
        pytest.skip(f"no OpenGL context: {exc}")
    try:
        frame = r.render(FRAME, scene.camera_paths[0])
    finally:
        r.release()
    agent_id = int(scene.agents(FRAME).agent_ids[scene.agent_row(MARKED_AGENT)])
    mine = frame.ids == agent_id
    assert mine.sum() > 300
    rgb = frame.color[mine].astype(float)
    red = (rgb[:, 0] > 1.5 * rgb[:, 1]) & (rgb[:, 0] > 1.5 * rgb[:, 2])
    blue = (rgb[:, 2] > 1.5 * rgb[:, 0]) & (rgb[:, 2] > 1.5 * rgb[:, 1])
    green = (rgb[:, 1] > 1.5 * rgb[:, 0]) & (rgb[:, 1] > 1.5 * rgb[:, 2])
    assert red.mean() > 0.15 and blue.mean() > 0.1 and green.mean() > 0.01, (red.mean(), blue.mean(), green.mean())
    rows = np.nonzero(mine)[0]
    assert rows[green].mean() < rows[red].mean() < rows[blue].mean()


def test_the_preview_draws_the_eyes_and_mouth_in_their_rows(dialogue_shot, tmp_path):
    """A close-up of agent A's face from in front of its head: the eyes' whites and the irises and mouth
    wear their own palette rows (the last two: the shader's second weight pair and its remainder)."""
    pytest.importorskip("moderngl")
    from dataclasses import replace

    from usdcrowd.core.errors import UsdcrowdError
    from usdcrowd.core.view import look_at
    from usdcrowd.render.preview import LodSettings, PreviewRenderer
    from usdcrowd.scenario.shot_scene import ShotScene

    scene = ShotScene(_marked_stage(dialogue_shot, tmp_path))
    row = scene.agent_row(MARKED_AGENT)
    joints = scene.agents(FRAME).joints_world[row]
    head = joints[2, 3, :3] + 0.125 * joints[2, 2, :3]            # up the head joint's +Z to the face
    eye = head + 0.45 * joints[2, 0, :3] / np.linalg.norm(joints[2, 0, :3])   # in front, along its +X
    try:
        r = PreviewRenderer(scene, 320, 180, lod_settings=LodSettings(enabled=False))
    except UsdcrowdError as exc:
        pytest.skip(f"no OpenGL context: {exc}")
    try:
        cam = replace(scene.camera(scene.camera_paths[0], FRAME), cam_to_world=look_at(eye, head)[0])
        frame = r.render_poses(r.poses(FRAME), cam, FRAME)
    finally:
        r.release()
    mine = frame.ids == int(scene.agents(FRAME).agent_ids[row])
    assert mine.mean() > 0.2, "the face must fill the frame"
    rgb = frame.color[mine].astype(float)
    r_, g, b = rgb[:, 0], rgb[:, 1], rgb[:, 2]
    cyan = (g > 2 * r_) & (b > 2 * r_)                              # MARKED eye whites
    magenta = (r_ > 2 * g) & (b > 2 * g)                            # MARKED irises and mouth
    assert cyan.sum() > 20 and magenta.sum() > 20, (cyan.sum(), magenta.sum())


def test_an_agent_given_one_colour_wears_it_all_over(dialogue_shot, tmp_path):
    """A stage (or an older shot) that authors a single displayColor on a body: that colour everywhere."""
    from usdcrowd.scenario.shot_scene import ShotScene

    path = tmp_path / "one.usda"
    path.write_text(_over_body(dialogue_shot, MARKED_AGENT,
                               'color3f[] primvars:displayColor = [(0.1, 0.2, 0.3)] (interpolation = "constant")'))
    scene = ShotScene(path)
    poses = scene.agents(FRAME)
    row = scene.agent_row(MARKED_AGENT)
    assert np.allclose(poses.palette[row], [0.1, 0.2, 0.3])
    others = np.delete(np.arange(len(poses)), row)
    assert all(len(np.unique(poses.palette[k].round(5), axis=0)) > 1 for k in others)


def test_a_palette_that_does_not_fit_the_body_is_a_one_line_error(dialogue_shot, tmp_path):
    from usdcrowd.core.errors import StageError
    from usdcrowd.scenario.shot_scene import ShotScene

    path = tmp_path / "bad.usda"
    path.write_text(_over_body(dialogue_shot, "/World/Crowd/Pair/B",
                               'color3f[] primvars:displayColor = [(0.1, 0.2, 0.3), (0.3, 0.2, 0.1)] '
                               '(interpolation = "vertex")'))
    with pytest.raises(StageError, match=r"Pair/B/Body.*primvars:displayColor.*2 colours"):
        ShotScene(path).agents(FRAME)


def test_mitsuba_reads_each_faces_roughness_from_its_material(dialogue_shot):
    """The agents' BSDF takes roughness per face: that of the material bound to the face's subset."""
    pytest.importorskip("mitsuba")
    from pxr import Usd, UsdGeom, UsdShade

    from usdcrowd.render.final.build import AGENTS_KEY, build_scene
    from usdcrowd.render.final.variant import activate, choose_variant
    from usdcrowd.scenario.shot_scene import ShotScene

    activate(choose_variant())
    shot = ShotScene(dialogue_shot)
    built = build_scene(shot, shot.camera(shot.camera_paths[0], FRAME), 64, 36, 4, 2, FRAME)
    shape = next(s for s in built.scene.shapes() if s.id() == AGENTS_KEY)
    assert "face_roughness" in str(shape.bsdf())
    got = np.array(built.params[f"{AGENTS_KEY}.face_roughness"]).reshape(len(shot.agent_paths), -1)
    # Expected straight from USD: each subset's bound UsdPreviewSurface roughness on its faces.
    stage = Usd.Stage.Open(str(dialogue_shot))
    for row, path in enumerate(shot.agent_paths):
        mesh = UsdGeom.Mesh(stage.GetPrimAtPath(f"{path}/Body"))
        expected = np.full(got.shape[1], np.nan)
        for subset in UsdGeom.Subset.GetGeomSubsets(mesh):
            shader = UsdShade.MaterialBindingAPI(subset.GetPrim()).ComputeBoundMaterial()[0].ComputeSurfaceSource()[0]
            expected[np.array(subset.GetIndicesAttr().Get())] = shader.GetInput("roughness").Get()
        assert np.allclose(got[row], expected, atol=1e-6)
    assert len(np.unique(got)) == len(REGIONS)


def test_validate_names_a_palette_that_does_not_fit_the_body(dialogue_shot, tmp_path):
    from usdcrowd.jobs.validation import validate

    assert not [p for p in validate(dialogue_shot) if p.severity == "error" and "displayColor" in p.attribute]
    path = tmp_path / "bad.usda"
    path.write_text(_over_body(dialogue_shot, "/World/Crowd/Pair/B",
                               'color3f[] primvars:displayColor = [(0.1, 0.2, 0.3), (0.3, 0.2, 0.1)] '
                               '(interpolation = "vertex")'))
    errors = [p for p in validate(path) if p.severity == "error"]
    assert [(p.prim, p.attribute) for p in errors] == [("/World/Crowd/Pair/B/Body", "primvars:displayColor")]
    assert "2 colours" in errors[0].message and "7" in errors[0].message
