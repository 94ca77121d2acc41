"""Final frames with Mitsuba: the analytic box, exact ids, EXR, baselines, resume, executors."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mitsuba")
pytest.importorskip("OpenEXR")

from usdcrowd.render.final.exr import ID_TABLE, read_frame_exr  # noqa: E402
from usdcrowd.render.final.frame import FrameRenderer  # noqa: E402
from usdcrowd.scenario.shot_scene import SCENERY_ID_BASE, ShotScene
from usdcrowd.render.sequence import Manifest, frame_files, render_sequence, verify_frame  # noqa: E402
from usdcrowd.render.settings import settings_from_preset  # noqa: E402

from tests.helpers.paths import BASELINES, FAILURES  # noqa: E402
from tests.helpers.render import BOX_STAGE, dof_box_stage, edge_crossings, edge_width  # noqa: E402
from tests.helpers.shots import HEADER  # noqa: E402
from tests.helpers.tools import load_tool  # noqa: E402

W, H = 64, 48


@pytest.fixture(scope="module")
def box_frame(tmp_path_factory):
    path = tmp_path_factory.mktemp("box") / "box.usda"
    path.write_text(HEADER.format(up="Z", mpu=1, end=1) + BOX_STAGE)
    renderer = FrameRenderer(path, "/World/Cam", (W, H), spp=16, max_depth=2)
    return renderer, renderer.render(1)


def test_box_depth_and_projection_are_exact_to_the_pixel(box_frame):
    renderer, r = box_frame
    cam = r.camera
    # The front face's corners, projected with the camera model every exporter uses.
    corners = np.array([[x, 9.0, z] for x in (-1, 1) for z in (-1, 1)])
    uv, z = cam.project(corners, W, H)
    assert np.allclose(z, 9.0)
    u0, v0 = uv.min(0)
    u1, v1 = uv.max(0)
    cols = (np.arange(W) + 0.5 > u0) & (np.arange(W) + 0.5 < u1)
    rows = (np.arange(H) + 0.5 > v0) & (np.arange(H) + 0.5 < v1)
    expected = rows[:, None] & cols[None, :]
    box_id = next(s.shape_id for s in renderer.shot.scenery if s.path == "/World/Box")
    assert np.array_equal(r.gt.ids == box_id, expected)
    assert set(np.unique(r.gt.ids)) == {0, box_id}
    # z-depth is the plane's distance, exactly; distance grows off axis as 1 / cos.
    assert np.allclose(r.gt.depth_z[expected], 9.0, atol=1e-4)
    k = cam.intrinsics(W, H)
    yy, xx = np.nonzero(expected)
    ray_len = np.sqrt(1 + ((xx + 0.5 - k[0, 2]) / k[0, 0]) ** 2 + ((yy + 0.5 - k[1, 2]) / k[1, 1]) ** 2)
    assert np.allclose(r.gt.depth_distance[expected], 9.0 * ray_len, atol=1e-4)
    assert np.isinf(r.gt.depth_z[~expected]).all()
    # Normals face the camera (-Y), positions lie on the face, albedo is the display colour.
    assert np.allclose(r.gt.normal[expected], (0, -1, 0), atol=1e-5)
    assert np.allclose(r.gt.position[expected][:, 1], 9.0, atol=1e-4)
    assert np.allclose(r.gt.albedo[expected], 0.5, atol=1e-5)


def test_beauty_sees_the_box_where_the_camera_model_puts_it(box_frame):
    """The Mitsuba sensor and CameraView.project agree: the box is dark exactly where the ids say."""
    _, r = box_frame
    lum = r.beauty.mean(-1)
    inside = r.gt.ids > 0
    # Away from the silhouette: inside ~ albedo * sky, outside = sky.
    from scipy.ndimage import binary_erosion

    # Mitsuba's Gaussian filter reaches 2 pixels: look 3 pixels away from the edge.
    core, outside = binary_erosion(inside, iterations=3), binary_erosion(~inside, iterations=3)
    assert np.allclose(lum[outside], 1.0, atol=1e-3)
    # The lit side of a principled grey under a white sky: albedo 0.5 plus the specular layer (0.538-0.540
    # at 256 spp with the independent, multijitter, stratified and low-discrepancy samplers alike).
    assert lum[core].mean() == pytest.approx(0.54, abs=0.03)
    assert lum[core].max() < 0.8


def test_animated_scenery_moves_between_frames_without_a_rebuild(tmp_path):
    stage = BOX_STAGE.replace("double3 xformOp:translate = (0, 10, 0)",
                              "double3 xformOp:translate.timeSamples = {1: (0, 10, 0), 2: (2, 10, 0)}")
    path = tmp_path / "moving.usda"
    path.write_text(HEADER.format(up="Z", mpu=1, end=2) + stage)
    renderer = FrameRenderer(path, "/World/Cam", (W, H), spp=1, max_depth=2)
    scene = renderer.built.scene
    a, b = renderer.render(1), renderer.render(2)
    assert renderer.built.scene is scene and len(renderer.built.animated) == 1
    cols_a = np.nonzero((a.gt.ids > 0).any(0))[0]
    cols_b = np.nonzero((b.gt.ids > 0).any(0))[0]
    # 2 m to the right at 9 m: f * 2 / 9 pixels.
    shift = a.camera.intrinsics(W, H)[0, 0] * 2 / 9
    assert cols_b.mean() - cols_a.mean() == pytest.approx(shift, abs=1.0)


TEXTURED_QUAD = '''
def Xform "World"
{
    def Mesh "Quad" (prepend apiSchemas = ["MaterialBindingAPI"])
    {
        int[] faceVertexCounts = [4]
        int[] faceVertexIndices = [0, 1, 2, 3]
        point3f[] points = [(-1, 9, -1), (1, 9, -1), (1, 9, 1), (-1, 9, 1)]
        texCoord2f[] primvars:st = [(0, 0), (1, 0), (1, 1), (0, 1)] (interpolation = "vertex")
        rel material:binding = </World/Mat>
    }
    def Material "Mat"
    {
        token outputs:surface.connect = </World/Mat/PBR.outputs:surface>
        def Shader "PBR"
        {
            uniform token info:id = "UsdPreviewSurface"
            color3f inputs:diffuseColor.connect = </World/Mat/Tex.outputs:rgb>
            token outputs:surface
        }
        def Shader "Tex"
        {
            uniform token info:id = "UsdUVTexture"
            asset inputs:file = @./tex.png@
            float3 outputs:rgb
        }
    }
    def DomeLight "Sky"
    {
        float inputs:intensity = 1
    }
    def Camera "Cam"
    {
        float focalLength = 0.24
        float horizontalAperture = 0.36
        float verticalAperture = 0.27
        float3 xformOp:rotateXYZ = (90, 0, 0)
        uniform token[] xformOpOrder = ["xformOp:rotateXYZ"]
    }
}
'''


def test_textures_keep_their_orientation(tmp_path):
    """USD st has its origin at the image's bottom left: the top of the texture is the top of the quad."""
    from PIL import Image

    img = np.zeros((8, 8, 3), np.uint8)
    img[:4] = (255, 0, 0)
    img[4:] = (0, 0, 255)
    Image.fromarray(img).save(tmp_path / "tex.png")
    (tmp_path / "quad.usda").write_text(HEADER.format(up="Z", mpu=1, end=1) + TEXTURED_QUAD)
    r = FrameRenderer(tmp_path / "quad.usda", "/World/Cam", (W, H), spp=1, max_depth=2).render(1)
    ys, xs = np.nonzero(r.gt.ids > 0)
    x = int(xs.mean())
    assert np.allclose(r.gt.albedo[ys.min() + 1, x], (1, 0, 0), atol=1e-3)
    assert np.allclose(r.gt.albedo[ys.max() - 1, x], (0, 0, 1), atol=1e-3)


@pytest.mark.parametrize("up, dome, pole, sky_up", [
    ("Y", "DomeLight", "", True),                          # DomeLight: the pole is +Y, the stage's up here
    ("Z", "DomeLight", "", False),                         # ... and on a Z-up stage too: the sky is on its side
    ("Z", "DomeLight_1", "", True),                        # DomeLight_1: poleAxis "scene", the stage's up axis
    ("Z", "DomeLight_1", 'uniform token poleAxis = "Y"', False),
    ("Y", "DomeLight_1", 'uniform token poleAxis = "Z"', False),
    ("Y", "DomeLight_1", "", True),
])
def test_textured_dome_puts_its_pole_where_usdlux_says(tmp_path, up, dome, pole, sky_up):
    """A lat-long sky (blue top half, brown bottom half) seen by a level camera, Y-up and Z-up stages."""
    from PIL import Image

    sky = np.zeros((32, 64, 3), np.uint8)
    sky[:16], sky[16:] = (120, 160, 255), (60, 50, 40)
    Image.fromarray(sky).save(tmp_path / "sky.png")
    level = "" if up == "Y" else "float3 xformOp:rotateXYZ = (90, 0, 0)\n        uniform token[] xformOpOrder = [\"xformOp:rotateXYZ\"]"
    (tmp_path / "sky.usda").write_text(HEADER.format(up=up, mpu=1, end=1) + f'''
def Xform "World"
{{
    def {dome} "Sky"
    {{
        asset inputs:texture:file = @./sky.png@
        {pole}
    }}
    def Camera "Cam"
    {{
        float focalLength = 0.24
        float horizontalAperture = 0.36
        {level}
    }}
}}
''')
    r = FrameRenderer(tmp_path / "sky.usda", "/World/Cam", (W, H), spp=4, max_depth=2).render(1)
    top, bottom = r.beauty[: H // 4].mean((0, 1)), r.beauty[-H // 4:].mean((0, 1))
    up_sky = top[2] > top[0] and bottom[0] > bottom[2]
    assert up_sky == sky_up, (top, bottom)


def test_scalar_fallback_gives_the_same_ground_truth(box_frame, tmp_path):
    """scalar_rgb (no JIT) casts one ray at a time through the same code path: same ids, same depth."""
    renderer, r = box_frame
    scalar = FrameRenderer(renderer.shot, "/World/Cam", (W, H), spp=4, max_depth=2, variant="scalar_rgb").render(1)
    assert np.array_equal(scalar.gt.ids, r.gt.ids)
    assert np.allclose(scalar.gt.depth_z, r.gt.depth_z, atol=1e-4)
    assert scalar.beauty.shape == (H, W, 3)
    renderer.render(1)                                                   # switching back works


def test_id_pass_is_identical_across_two_runs(walking_museum, tmp_path):
    """A second process (another shape order inside Mitsuba, its own BVH build) gives the same ids and
    the same beauty, bit for bit."""
    script = tmp_path / "ids.py"
    script.write_text(
        "import sys, numpy as np\nimport usdcrowd\nfrom usdcrowd.render.final.frame import FrameRenderer\n"
        "r = FrameRenderer(sys.argv[1], None, (96, 54), spp=4, max_depth=2).render(6)\n"
        "np.save(sys.argv[2], r.gt.ids)\nnp.save(sys.argv[3], r.beauty)\n")
    subprocess.run([sys.executable, str(script), walking_museum, str(tmp_path / "ids.npy"), str(tmp_path / "b.npy")],
                   check=True)
    here = FrameRenderer(walking_museum, None, (96, 54), spp=4, max_depth=2).render(6)
    other = np.load(tmp_path / "ids.npy")
    assert np.array_equal(here.gt.ids, other)
    assert np.array_equal(here.beauty, np.load(tmp_path / "b.npy"))
    agents = set(np.unique(here.gt.ids)) & set(range(1, SCENERY_ID_BASE))
    assert agents and agents <= set(ShotScene(walking_museum).agents(6).agent_ids.tolist())
    assert all(i >= SCENERY_ID_BASE for i in np.unique(here.gt.ids) if i not in agents and i != 0)


@pytest.mark.parametrize("spp", [8, 12])
def test_the_beauty_is_the_same_bytes_run_after_run(walking_museum, spp):
    """Two renders of one frame on two threads: every pixel identical (issue 16: same command, same bytes);
    12 spp is taken as 8 + 4."""
    r = FrameRenderer(walking_museum, None, (640, 360), spp=spp, max_depth=3, ground_truth=False, threads=2)
    first, second = r.render(6).beauty, r.render(6).beauty
    assert first.mean() > 0
    assert np.array_equal(first, second), f"{np.mean(first != second):.1%} of the values differ"


@pytest.fixture(scope="module")
def small_sequence(walking_museum, tmp_path_factory):
    out = tmp_path_factory.mktemp("seq")
    settings = settings_from_preset("groundtruth", resolution=(96, 54), spp=4)
    r = render_sequence(walking_museum, out, frames=np.array([1.0, 2.0, 3.0, 4.0]), settings=settings,
                        executor="inline", progress=False)
    return r, settings


def test_exr_has_named_channels_ids_and_the_id_table(small_sequence):
    r, _ = small_sequence
    header, ch = read_frame_exr(Path(r.out_dir) / frame_files(1, True)["exr"])
    assert {"R", "G", "B", "depth.z", "depth.distance", "normal.X", "position.Z", "albedo.G", "id"} <= set(ch)
    assert ch["id"].dtype == np.uint32 and ch["depth.z"].dtype == np.float32
    table = header[ID_TABLE]
    assert set(np.unique(ch["id"])) - {0} <= set(table)
    assert table[100] == "/World/Crowd/Visitors/Students/Teacher"
    finite = np.isfinite(ch["depth.z"])
    assert (ch["depth.distance"][finite] >= ch["depth.z"][finite] - 1e-4).all()


def test_a_killed_render_resumes_and_only_redoes_what_is_missing(walking_museum, small_sequence):
    r, settings = small_sequence
    out = Path(r.out_dir)
    (out / frame_files(2, True)["exr"]).unlink()                              # lost
    png = out / frame_files(3, True)["png"]
    png.write_bytes(png.read_bytes()[:100])                                    # damaged
    again = render_sequence(walking_museum, out, frames=np.array([1.0, 2.0, 3.0, 4.0]), settings=settings,
                            executor="inline", progress=False)
    assert again.rendered == [2.0, 3.0] and again.skipped == [1.0, 4.0]
    manifest = Manifest(out, json.loads((out / "manifest.json").read_text())["header"])
    assert all(verify_frame(out, t, manifest, settings) for t in (1, 2, 3, 4))


def test_frames_written_but_not_in_the_manifest_are_adopted(small_sequence):
    r, settings = small_sequence
    out = Path(r.out_dir)
    doc = json.loads((out / "manifest.json").read_text())
    doc["frames"].pop("0004")
    (out / "manifest.json").write_text(json.dumps(doc))
    manifest = Manifest(out, doc["header"])
    assert verify_frame(out, 4.0, manifest, settings)
    assert manifest.frames["0004"]["adopted"]


def _diff_report(name, got, ref):
    FAILURES.mkdir(exist_ok=True)
    from usdcrowd.render.colour import write_png

    write_png(np.abs(got - ref) * 4.0, FAILURES / f"{name}.diff.png")
    write_png(got, FAILURES / f"{name}.got.png")
    write_png(ref, FAILURES / f"{name}.ref.png")
    return FAILURES / f"{name}.diff.png"


@pytest.mark.parametrize("name", ["museum_overview_f6"])
def test_render_matches_the_stored_baseline(walking_museum, name):
    """Statistical comparison: Monte Carlo noise differs between variants and versions, the picture must not."""
    make_baselines = load_tool("make_baselines")
    meta = json.loads((BASELINES / f"{name}.json").read_text())
    _, ref = read_frame_exr(BASELINES / f"{name}.exr")
    ref = np.stack([ref["R"], ref["G"], ref["B"]], -1)
    got = make_baselines.render_baseline(walking_museum, meta).beauty
    diff = np.abs(got - ref).mean(-1)
    scale = max(float(ref.mean()), 1e-3)
    mean_rel, p99_rel = diff.mean() / scale, np.percentile(diff, 99) / scale
    if mean_rel > meta["max_mean_rel"] or p99_rel > meta["max_p99_rel"]:
        where = _diff_report(name, got, ref)
        pytest.fail(f"{name}: mean {mean_rel:.3f} (max {meta['max_mean_rel']}), p99 {p99_rel:.3f} "
                    f"(max {meta['max_p99_rel']}); diff image {where}")


def test_variant_is_chosen_and_reported():
    from usdcrowd.render.final.variant import choose_variant, describe

    v = choose_variant()
    assert v in ("cuda_ad_rgb", "llvm_ad_rgb", "scalar_rgb")
    assert v in describe(v)
    from usdcrowd.core.errors import UsdcrowdError

    with pytest.raises(UsdcrowdError, match="not available"):
        choose_variant("no_such_variant")


def test_lights_follow_the_documented_radiometric_mapping():
    from usdcrowd.render.final.lights import emitted
    from usdcrowd.scenario.shot_scene import Light

    lamp = Light("/L", "sphere", np.array([1.0, 0.5, 0.25]), 8.0, np.eye(4), radius=0.5)
    assert np.allclose(emitted(lamp), [8, 4, 2])
    lamp.normalize = True
    assert np.allclose(emitted(lamp), np.array([8, 4, 2]) / (4 * np.pi * 0.25))
    sun = Light("/S", "distant", np.ones(3), 3.0, np.eye(4), angle=0.5, normalize=False)
    assert np.allclose(emitted(sun), 3.0)


def _sphere_lamp(to_world_3x3, centre, radius=0.25, intensity=5.0):
    from usdcrowd.scenario.shot_scene import Light

    m = np.eye(4)
    m[:3, :3] = to_world_3x3
    m[3, :3] = centre
    return Light("/Lamp", "sphere", np.ones(3), intensity, m, radius=radius)


def test_a_sphere_light_is_analytic_and_lights_as_usdlux_means():
    """A SphereLight is Mitsuba's analytic sphere (its radius times any even scale left in its transform,
    centred where the transform puts it); a white diffuse floor right under it, d from its centre, gets
    the irradiance E = pi L (R / d)^2 and so shows radiance L (R / d)^2. A transform Mitsuba's sphere
    cannot take (a shear) leaves it a mesh."""
    from usdcrowd.render.final import integrator, variant
    from usdcrowd.render.final.lights import emitters

    mi = variant.activate(variant.choose_variant(None))
    c, s = np.cos(0.5), np.sin(0.5)
    turn_and_scale = 2.0 * np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]])
    lamp = emitters([_sphere_lamp(turn_and_scale, [0.3, -0.2, 1.5])])["light_0"]
    assert lamp["type"] == "sphere"
    assert lamp["radius"] == pytest.approx(0.5) and np.allclose(lamp["center"], [0.3, -0.2, 1.5])
    sheared = emitters([_sphere_lamp(np.array([[1.0, 0, 0], [0.5, 1, 0], [0, 0, 1]]), [0, 0, 0])])["light_0"]
    assert isinstance(sheared, mi.Mesh)
    if mi.variant().startswith("scalar"):
        pytest.skip("the every-light tracer runs on the JIT variants only")
    integrator.register()
    T = mi.ScalarTransform4f
    scene = mi.load_dict({
        "type": "scene", "integrator": {"type": integrator.NAME, "max_depth": 2},
        "sensor": {"type": "perspective", "fov": 2, "to_world": T().look_at(origin=[0.3, -2.0, 0.5],
                                                                           target=[0.3, -0.2, 0], up=[0, 0, 1]),
                   "film": {"type": "hdrfilm", "width": 8, "height": 8, "rfilter": {"type": "box"}},
                   "sampler": {"type": "multijitter"}},
        "floor": {"type": "rectangle", "to_world": T().translate([0.3, -0.2, 0]).scale(3),
                  "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": 1.0}}},
        "lamp": lamp})
    seen = float(np.array(mi.render(scene, spp=256)).mean())
    assert seen == pytest.approx(5.0 * (0.5 / 1.5) ** 2, rel=0.01)


def test_materials_map_preview_surface_inputs():
    from usdcrowd.render.final.materials import bsdf_dict
    from usdcrowd.scenario.shot_scene import Material

    d = bsdf_dict(Material(np.array([0.2, 0.3, 0.4]), roughness=0.3, metallic=1.0, opacity=0.5))
    assert d["type"] == "mask" and d["opacity"]["value"] == [0.5] * 3
    inner = d["bsdf"]
    assert inner["type"] == "principled" and inner["roughness"] == 0.3 and inner["metallic"] == 1.0
    assert inner["base_color"]["value"] == [0.2, 0.3, 0.4]
    tex = bsdf_dict(Material(base_color_texture="/tmp/wood.png"))
    assert tex["base_color"] == {"type": "bitmap", "filename": "/tmp/wood.png", "wrap_mode": "repeat"}


def test_display_transform_is_colour_science_srgb():
    import colour

    from usdcrowd.render.colour import convert, to_display

    grey = np.full((1, 1, 3), 0.18)
    expected = np.round(colour.cctf_encoding(0.18, function="sRGB") * 255)
    assert to_display(grey)[0, 0, 0] == expected
    assert to_display(grey, exposure=1.0)[0, 0, 0] == np.round(colour.cctf_encoding(0.36, function="sRGB") * 255)
    rgb = np.array([[[0.7, 0.2, 0.1]]])
    back = convert(convert(rgb, "sRGB", "ACEScg"), "ACEScg", "sRGB")
    assert np.allclose(back, rgb, atol=1e-4)                   # float32 storage
    assert np.abs(to_display(convert(rgb, "sRGB", "ACEScg"), "ACEScg").astype(int)
                  - to_display(rgb).astype(int)).max() <= 1


def test_presets_are_read_and_overridden():
    from usdcrowd.core.errors import UsdcrowdError

    s = settings_from_preset("preview", spp=3)
    assert s.spp == 3 and s.resolution == (320, 180) and not s.ground_truth
    assert settings_from_preset("final").working_space == "ACEScg"
    with pytest.raises(UsdcrowdError, match="unknown render preset"):
        settings_from_preset("nope")


def test_cli_render_writes_frames_and_reports_user_errors(walking_museum, tmp_path, capsys):
    from usdcrowd.cli import main

    out = tmp_path / "r"
    assert main(["render", walking_museum, "-o", str(out), "--frames", "2", "--resolution", "48x27", "--spp", "2",
                 "--executor", "inline", "--no-progress"]) == 0
    assert "rendered 1 frame(s)" in capsys.readouterr().out
    assert (out / "exr/frame.0002.exr").exists() and (out / "coco.json").exists()
    assert main(["render", walking_museum, "-o", str(out), "--camera", "/World/Nope", "--frames", "2"]) == 2
    assert "not a camera" in capsys.readouterr().err
    assert main(["render", walking_museum, "-o", str(out), "--preset", "nope", "--frames", "2"]) == 2


def test_local_worker_processes_render_frames(walking_museum, tmp_path):
    settings = settings_from_preset("groundtruth", resolution=(64, 36), spp=2)
    r = render_sequence(walking_museum, tmp_path, frames=np.array([1.0, 2.0, 3.0]), settings=settings,
                        executor="local", workers=2, progress=False)
    assert r.rendered == [1.0, 2.0, 3.0]
    inline = FrameRenderer(walking_museum, None, (64, 36), spp=2).render(2)
    _, ch = read_frame_exr(tmp_path / frame_files(2, True)["exr"])
    assert np.array_equal(ch["id"], inline.gt.ids)


@pytest.mark.slow
@pytest.mark.ray
def test_ray_executor_on_a_local_cluster(walking_museum, tmp_path):
    pytest.importorskip("ray")
    settings = settings_from_preset("groundtruth", resolution=(64, 36), spp=2)
    r = render_sequence(walking_museum, tmp_path, frames=np.array([1.0, 2.0, 3.0, 4.0]), settings=settings,
                        executor="ray", workers=2, progress=False)
    assert r.rendered == [1.0, 2.0, 3.0, 4.0]
    manifest = Manifest(tmp_path, json.loads((tmp_path / "manifest.json").read_text())["header"])
    assert all(verify_frame(tmp_path, t, manifest, settings) for t in r.times)


@pytest.mark.slow
@pytest.mark.ray
def test_a_users_mistake_found_on_a_ray_worker_is_one_line(tmp_path, capsys):
    """A damaged frame found by a Ray actor: the CLI prints the StageError's one line, not Ray's traceback."""
    pytest.importorskip("ray")
    from tests.helpers.frames import straight_walk
    from tests.helpers.damage import spoil_root_translation

    import usdcrowd.core.resources as res
    from usdcrowd.cli import main
    from usdcrowd.jobs.pipeline import author_shot

    shot = tmp_path / "shot"
    author_shot(res.data_dir("stages") / "museum.usda", shot, lambda sc: [straight_walk(sc.agents, sc.time)],
                frames=(1, 4), progress=False)
    spoil_root_translation(shot / "crowd.usdc", 3.0, float("nan"))
    capsys.readouterr()
    code = main(["render", str(shot / "shot.usda"), "-o", str(tmp_path / "r"), "--frames", "3", "--executor", "ray",
                 "--resolution", "32x18", "--spp", "1", "--no-progress"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "not a finite value at time 3" in err, err


@pytest.mark.parametrize("f_stop, focus", [(0.0, 3.0), (1.0, 9.0), (1.0, 3.0), (2.0, 5.0)])
def test_depth_of_field_blurs_as_a_thin_lens_of_the_cameras_fstop(tmp_path, f_stop, focus):
    """The box's edge (9 m away) spreads as a thin lens predicts: a disc of diameter A f |d - s| / (d (s - f))."""
    path = dof_box_stage(tmp_path, f_stop, focus)
    w, h = 256, 192
    r = FrameRenderer(path, "/World/Cam", (w, h), spp=256, max_depth=2).render(1)
    f, d = 0.1, 9.0                                                # metres: 100 mm lens, the box's face
    if f_stop == 0:
        assert not r.camera.depth_of_field
        assert edge_width(r.beauty) < 1.0
        return
    assert r.camera.aperture_radius == pytest.approx(f / (2 * f_stop))
    blur_m = (f / f_stop) * f * abs(d - focus) / (d * (focus - f))
    blur_px = blur_m / 0.036 * w
    # A uniform disc of diameter D spreads an edge's 25-75 % over 0.404 D.
    expected = max(0.404 * blur_px, 0.5)
    measured = edge_width(r.beauty)
    print(f"fStop {f_stop}, focus {focus} m: edge 25-75 % over {measured:.2f} px, thin lens {expected:.2f} px")
    if focus == d:
        assert measured < 1.0
    else:
        assert measured == pytest.approx(expected, rel=0.2), (measured, expected, blur_px)
    # The ground truth stays pinhole: ids exactly where the camera model projects the box.
    pinhole = FrameRenderer(path, "/World/Cam", (w, h), spp=1, max_depth=2)
    assert np.array_equal(pinhole.render(1).gt.ids, r.gt.ids)


def test_a_light_shape_carries_its_own_id_where_the_camera_sees_it(tmp_path):
    """A SphereLight in view: the id pass holds LIGHT_ID_BASE + its index on the pixels whose rays hit the sphere."""
    from usdcrowd.render.final.exr import read_frame_exr
    from usdcrowd.render.sequence import render_sequence
    from usdcrowd.render.settings import settings_from_preset
    from usdcrowd.core.shading import LIGHT_ID_BASE

    stage = BOX_STAGE.replace('''    def DomeLight "Sky"''', '''    def SphereLight "Lamp"
    {
        float inputs:radius = 0.4
        float inputs:intensity = 5
        double3 xformOp:translate = (2.2, 8, 0.5)
        float xformOp:rotateZ = 30
        float3 xformOp:scale = (1.5, 1.5, 1.5)
        uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateZ", "xformOp:scale"]
    }
    def DomeLight "Sky"''')
    path = tmp_path / "lamp.usda"
    path.write_text(HEADER.format(up="Z", mpu=1, end=1) + stage)
    w, h = 160, 120
    r = FrameRenderer(path, "/World/Cam", (w, h), spp=1, max_depth=2).render(1)
    lamp = [i for i, p in r.id_paths.items() if p == "/World/Lamp"]
    assert lamp == [LIGHT_ID_BASE + 0]                 # the first (and only sphere) light of the shot
    # Analytic: pixel-centre rays against the sphere of radius 0.4 x 1.5 (Mitsuba's analytic sphere: the same
    # pixels, but for a grazing ray whose precision may differ by backend).
    k = r.camera.intrinsics(w, h)
    uu, vv = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    d_cam = np.stack([(uu - k[0, 2]) / k[0, 0], -(vv - k[1, 2]) / k[1, 1], -np.ones_like(uu)], -1)
    d = d_cam @ r.camera.cam_to_world[:3, :3]
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    oc = r.camera.position - np.array([2.2, 8, 0.5])
    b = d @ oc
    hit = b * b - (oc @ oc - 0.6 ** 2) > 0
    # The box (x from -1 to 1 at y 9-11) is behind the lamp: where the lamp is, the lamp wins.
    seen = r.gt.ids == lamp[0]
    assert hit.sum() > 100
    assert (seen != hit).sum() <= 2, ((seen != hit).sum(), hit.sum())
    # Named in the EXR's id table, as scenery is.
    out = render_sequence(path, tmp_path / "render", camera="/World/Cam", frames=[1],
                          settings=settings_from_preset("groundtruth", resolution=(w, h), spp=1), progress=False)
    header, ch = read_frame_exr(tmp_path / "render" / "exr" / "frame.0001.exr")
    assert np.array_equal(ch["id"], r.gt.ids) and out.rendered
    assert header["usdcrowd:idTable"][LIGHT_ID_BASE] == "/World/Lamp"


SUN_STAGE = '''
def Xform "World"
{
    def Mesh "Ground"
    {
        int[] faceVertexCounts = [4]
        int[] faceVertexIndices = [0, 1, 2, 3]
        point3f[] points = [(-20, -20, 0), (20, -20, 0), (20, 20, 0), (-20, 20, 0)]
        color3f[] primvars:displayColor = [(0.8, 0.8, 0.8)]
    }
    def Cube "Roof"
    {
        double size = 1
        color3f[] primvars:displayColor = [(0.5, 0.5, 0.5)]
        double3 xformOp:translate = (-5, 0, 4)
        float3 xformOp:scale = (10, 10, 0.2)
        uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:scale"]
    }
    def DistantLight "Sun"
    {
        bool inputs:normalize = true
        float inputs:intensity = 3
        float inputs:angle = {angle}
        float3 xformOp:rotateXYZ = (0, -45, 0)
        uniform token[] xformOpOrder = ["xformOp:rotateXYZ"]
    }
    def Camera "Cam"
    {
        float focalLength = 0.24
        float horizontalAperture = 0.36
        float verticalAperture = 0.36
        float2 clippingRange = (0.1, 100)
        double3 xformOp:translate = (4, 0, 12)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }
}
'''


@pytest.mark.parametrize("angle", [0.0, 5.0, 10.0])
def test_the_suns_angle_gives_the_penumbra_a_disc_of_that_size_casts(tmp_path, angle):
    """A roof's edge 4 m up, the sun 45 degrees from the zenith: the shadow's edge on the ground spreads over
    (4 / cos 45) * angle / cos 45 metres (the disc's full penumbra), the same irradiance outside it."""
    def lit_row(a):
        path = tmp_path / f"sun{a}.usda"
        path.write_text(HEADER.format(up="Z", mpu=1, end=1) + SUN_STAGE.replace("{angle}", str(a)))
        return FrameRenderer(path, "/World/Cam", (w, w), spp=256, max_depth=2).render(1).beauty.mean(-1)[60:140].mean(0)

    w = 200
    row = lit_row(angle)
    lit = float(np.median(row[-30:]))
    p = row / lit                                               # 0 in the shadow, 1 in the sun
    px_per_m = w / (2 * 12 * 18 / 24)                           # 12 m above the ground, 36 mm on 24 mm

    def crossing(level, start=70):                              # left of 70 px the camera sees the roof's top
        j = start + int(np.argmax(p[start:] >= level))
        return j - (p[j] - level) / (p[j] - p[j - 1])

    width = crossing(0.75) - crossing(0.25)
    full = 4 / np.cos(np.pi / 4) * np.radians(angle) / np.cos(np.pi / 4) * px_per_m
    print(f"sun angle {angle} deg: penumbra 25-75 % over {width:.2f} px, a disc predicts {0.404 * full:.2f} px")
    if angle == 0:
        assert width < 1.0
    else:
        assert width == pytest.approx(0.404 * full, rel=0.2)
        # The sun's irradiance does not depend on its size: the lit ground is as bright as under a point sun.
        assert lit == pytest.approx(float(np.median(lit_row(0.0)[-30:])), rel=0.02)
    # The edge itself is where the roof's edge casts it: x = 4 m, the image's centre column.
    assert abs(crossing(0.5) - w / 2) < 1.5


def test_an_unnormalised_sun_gives_its_discs_luminance_as_usdlux_says(tmp_path):
    """UsdLux: a DistantLight's intensity is its disc's luminance, and ``inputs:normalize`` divides it by the
    size factor pi sin^2(angle / 2), making the intensity the illuminance. So the same 10-degree sun lights the
    ground pi sin^2(5 deg) = 0.0239 times as brightly unnormalised (Blender reads it so too)."""
    from usdcrowd.core.shading import distant_illuminance

    def lit(normalize):
        path = tmp_path / f"sun{normalize}.usda"
        stage = SUN_STAGE.replace("{angle}", "10").replace("normalize = true", f"normalize = {normalize}")
        path.write_text(HEADER.format(up="Z", mpu=1, end=1) + stage)
        row = FrameRenderer(path, "/World/Cam", (64, 64), spp=64, max_depth=2).render(1).beauty.mean(-1)[20:44]
        return float(np.median(row[:, -10:]))

    assert lit("false") / lit("true") == pytest.approx(np.pi * np.sin(np.radians(5.0)) ** 2, rel=0.03)
    assert distant_illuminance(0.53, False) == pytest.approx(6.72e-5, rel=1e-3)
    assert distant_illuminance(0.53, True) == distant_illuminance(0.0, False) == 1.0
    assert distant_illuminance(180.0, False) == pytest.approx(np.pi)          # a hemisphere
    assert distant_illuminance(270.0, False) == pytest.approx(1.5 * np.pi)    # (2 - sin^2 135 deg) pi
    assert distant_illuminance(360.0, False) == pytest.approx(2 * np.pi)      # the whole sphere


def test_motion_blur_spreads_a_moving_edge_over_the_shutters_travel(tmp_path):
    """A box crossing the view at 2 m a frame, shutter 0.5: its edge ramps over the distance it moves while the
    shutter is open (a linear ramp: 25-75 % over half of it); the ground truth stays at the frame's time."""
    stage = BOX_STAGE.replace("double3 xformOp:translate = (0, 10, 0)",
                              "double3 xformOp:translate.timeSamples = {1: (-2, 10, 0), 2: (0, 10, 0), 3: (2, 10, 0)}")
    path = tmp_path / "moving.usda"
    path.write_text(HEADER.format(up="Z", mpu=1, end=3) + stage)
    w, h = 256, 192
    sharp = FrameRenderer(path, "/World/Cam", (w, h), spp=64, max_depth=2).render(2)
    blurred = FrameRenderer(path, "/World/Cam", (w, h), spp=256, max_depth=2, shutter=0.5, subframes=32).render(2)
    px_per_m = w / (2 * 9 * 18 / 24)                 # the box's front face is 9 m away; 36 mm on 24 mm
    ramp = 2.0 * 0.5 * px_per_m                      # metres a frame x frames open x pixels a metre
    width = edge_width(blurred.beauty)
    print(f"motion blur: edge 25-75 % over {width:.2f} px, the shutter's travel predicts {0.5 * ramp:.2f} px")
    assert edge_width(sharp.beauty) < 1.0
    # (measured a little wider: the box's side face turns into view as it moves off the axis)
    assert width == pytest.approx(0.5 * ramp, rel=0.2)
    # The shutter is centred on the frame: the blurred edge's middle is where the sharp edge is.
    assert abs(edge_crossings(blurred.beauty)[1] - edge_crossings(sharp.beauty)[1]) < 1.0
    np.testing.assert_array_equal(blurred.gt.ids, sharp.gt.ids)


@pytest.mark.parametrize("field, value", [("shutter", 2.0), ("subframes", 0), ("people_spp", -1), ("spp", 0),
                                          ("sampler", "magic"), ("working_space", "XYZ"), ("aovs", ("depth", "x"))])
def test_render_settings_are_checked_once_where_they_are_made(field, value):
    """A preset, the command line and the renderer itself all make a RenderSettings: one check, one message."""
    from usdcrowd.core.errors import UsdcrowdError
    from usdcrowd.render.settings import RenderSettings, settings_from_preset

    with pytest.raises(UsdcrowdError):
        RenderSettings(**{field: value})
    with pytest.raises(UsdcrowdError):
        settings_from_preset("groundtruth", **{field: value})
    assert settings_from_preset("groundtruth").fingerprint() == RenderSettings(
        **{k: v for k, v in vars(settings_from_preset("groundtruth")).items()}).fingerprint()
