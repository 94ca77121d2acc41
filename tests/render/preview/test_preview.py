"""The OpenGL preview: headless rendering, ids, depth, level of detail, outputs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from usdcrowd.character import rig
from usdcrowd.render.preview import instancing, lod
from usdcrowd.scenario.shot_scene import SCENERY_ID_BASE

from tests.helpers.paths import BASELINES, FAILURES
from tests.helpers.tools import load_tool

# Baseline comparison: a pixel fails when a channel differs by more than
# PIXEL_TOLERANCE code values; the test fails when more than
# FAILING_FRACTION of the pixels do (rasterisation may move an edge by a pixel).
PIXEL_TOLERANCE = 24
FAILING_FRACTION = 0.01


def _tool():
    return load_tool("make_preview_baselines")


@pytest.fixture(scope="module")
def tiny_shot(tmp_path_factory, gl):
    """The baseline's tiny shot: four agents walking straight, a block, sun and sky."""
    return _tool().make_tiny_shot(tmp_path_factory.mktemp("tiny"))


@pytest.fixture(scope="module")
def exact_renderer(tiny_shot, gl):
    """Full meshes everywhere (exact silhouettes), 320x180."""
    from usdcrowd.render.preview import LodSettings, PreviewRenderer

    r = PreviewRenderer(tiny_shot, 320, 180, ctx=gl, lod_settings=LodSettings(enabled=False))
    yield r
    r.release()


# ------------------------------------------------------------ pure functions
def test_boxes_from_ids_are_tight_and_exclusive():
    from usdcrowd.render.preview import boxes_from_ids

    ids = np.zeros((10, 12), np.uint32)
    ids[2:5, 3:7] = 4
    ids[8, 11] = 9
    ids[0:2, 0:2] = SCENERY_ID_BASE + 3
    assert boxes_from_ids(ids) == {4: (3, 2, 7, 5), 9: (11, 8, 12, 9)}
    assert boxes_from_ids(ids, include_scenery=True)[SCENERY_ID_BASE + 3] == (0, 0, 2, 2)
    assert boxes_from_ids(np.zeros((3, 3), np.uint32)) == {}


def test_octree_order_spreads_every_prefix_over_the_body():
    from usdcrowd.character.body import build_body

    pts = build_body().points
    order = instancing.octree_order(pts)
    assert sorted(order) == list(range(len(pts)))
    # The first 48 points reach from the feet to the head and both sides,
    # unlike the first 48 of the mesh's own order (the legs).
    first = pts[order[:48]]
    assert first[:, 2].min() < 0.2 and first[:, 2].max() > 1.5
    assert first[:, 1].min() < -0.1 and first[:, 1].max() > 0.1
    assert pts[:48, 2].max() < 1.0


def test_coarse_level_is_smaller_and_keeps_the_size_of_the_body():
    from usdcrowd.character.body import build_body

    b = build_body()
    lods = instancing.body_lods(b.points, b.face_vertex_indices.reshape(-1, 3), b.joint_indices, b.joint_weights,
                                regions=b.regions)
    full = lods.full.vertices[:, :3]
    # The full mesh carries each vertex's region one-hot (the last row, the face, as the remainder).
    rows = np.c_[lods.full.vertices[:, 9:15], 1 - lods.full.vertices[:, 9:15].sum(1)]
    assert np.array_equal(np.argmax(rows, 1), b.regions) and np.allclose(rows.max(1), 1.0)
    tris = [m.n_triangles for m in lods.meshes]
    assert tris[0] > 1000 and tris[1] < 0.6 * tris[0] and tris[2] < 0.2 * tris[0]
    for m in lods.meshes[1:]:
        # Quadric placement keeps the extent (thin arms, head top) within 4 cm.
        coarse = m.vertices[:, :3]
        assert np.abs(coarse.max(0) - full.max(0)).max() < 0.04 and np.abs(coarse.min(0) - full.min(0)).max() < 0.04
        assert np.allclose(m.vertices[:, 6:9].sum(1), 1.0, atol=1e-5)
        region = m.vertices[:, 9:15]
        assert region.min() >= 0 and region.sum(1).max() <= 1 + 1e-5
        # Merged vertices keep their regions: the crown is hair, the feet are shoes.
        top, bottom = np.argmax(coarse[:, 2]), np.argmin(coarse[:, 2])
        assert region[top, 3] > 0.9 and region[bottom, 4] > 0.9


def test_instance_records_skin_like_usdskel():
    """The vertex shader's arithmetic, replayed in numpy on the packed records."""
    from usdcrowd.character.body import build_body

    rng = np.random.default_rng(3)
    b = build_body()
    q = rig.quat_from_axis_angle(rng.normal(size=(5, 3, 3)), rng.uniform(-0.5, 0.5, (5, 3)))
    local = rig.compose_local(q, np.broadcast_to(rig.REST_TRANSLATIONS, (5, 3, 3)))
    root = np.tile(np.eye(4), (5, 1, 1))
    root[:, 3, :3] = rng.uniform(-5, 5, (5, 3))
    root[:, :3, :3] *= rng.uniform(0.9, 1.1, (5, 1, 1))
    world = rig.local_to_skel(local) @ root[:, None]
    skinning = rig.skinning_transforms(world)
    rec = instancing.pack_instances(skinning, np.zeros((5, 3)), np.arange(1, 6))
    # The compiled packer, from the joints themselves, writes the same records.
    palettes = rng.uniform(0, 1, (5, 4, 3))
    fast = instancing.pack_poses(world, palettes, np.arange(1, 6))
    assert np.allclose(fast, instancing.pack_instances(skinning, palettes, np.arange(1, 6)), atol=1e-6, rtol=0)
    assert fast[:, 9, 3].view(np.uint32).tolist() == [1, 2, 3, 4, 5]
    w = instancing.dense_weights(b.joint_indices, b.joint_weights)
    cols = np.einsum("vj,njcd->nvcd", w, rec[:, :9].reshape(5, 3, 3, 4))      # blended columns
    got = np.einsum("vd,nvcd->nvc", np.c_[b.points, np.ones(len(b.points))], cols)
    want = rig.skin_points(b.points, b.joint_indices, b.joint_weights, skinning)
    assert np.abs(got - want).max() < 1e-4
    assert rec[:, 9, 3].view(np.uint32).tolist() == [1, 2, 3, 4, 5]


def test_shadow_map_is_sized_to_the_screen_pixels():
    from usdcrowd.render.preview import shadows
    assert shadows.used_size(60.0, 0.044, 2048, texel_pixels=1.0) == 1408   # 60 m at 4.4 cm per pixel
    assert shadows.used_size(60.0, 0.022, 2048, texel_pixels=2.0) == 1408   # a texel to two pixels
    assert shadows.used_size(60.0, 0.005, 2048) == 2048        # never more than the map
    assert shadows.used_size(1.0, 0.05, 2048) == 512          # nor less than the floor
    assert shadows.used_size(60.0, None, 2048) == 2048
    view = np.eye(4)                                          # camera at the origin looking down -Z
    centres = np.array([[0.0, 0.0, -z] for z in (10.0, 20.0, 40.0)])
    assert shadows.pixel_footprint(centres, view, 1000.0, quantile=0.0) == pytest.approx(0.01)
    assert shadows.pixel_footprint(np.zeros((0, 3)), view, 1000.0) is None


def test_only_the_tallest_drawn_characters_keep_meshes_past_the_budget(rng):
    s = lod.LodSettings(max_meshes=150)
    px = rng.uniform(110.0, 900.0, 1000)          # all tall enough for the full mesh
    drawn = rng.random(1000) < 0.8
    levels = lod.choose_levels(px, s, drawn)
    meshed = levels == 0
    assert (meshed & drawn).sum() == 150
    # The kept ones are the 150 tallest of the drawn; the rest are impostors.
    assert px[meshed & drawn].min() > px[~meshed & drawn].max()
    assert set(levels[drawn & ~meshed].tolist()) == {s.impostor_level}
    # Under the budget, or with no limit, nothing changes.
    assert (lod.choose_levels(px[:100], s) == 0).all()
    assert (lod.choose_levels(px, lod.LodSettings(max_meshes=None)) == 0).all()


def test_impostor_texels_are_no_coarser_than_pixels_below_the_mesh_level():
    """Up to the default mesh level's height on screen, no part's picture has a texel wider than a pixel."""
    from usdcrowd.character.body import build_body
    from usdcrowd.render.preview import impostors

    b = build_body()
    faces = b.face_vertex_indices.reshape(-1, 3)
    parts = impostors.body_parts(b.points, faces, instancing.dense_weights(b.joint_indices, b.joint_weights))
    tallest = lod.LodSettings().mesh_levels[-1][0]
    pixel = rig.HEAD_TOP / tallest
    for part in parts:
        for e in impostors.ELEVATIONS:
            d = impostors.view_direction(0.0, e)
            _, _, hw, hh = impostors.view_basis(d, part)
            assert 2.0 * max(hw, hh) / impostors.CELL <= pixel, (part.half_height, np.degrees(e))


def test_levels_follow_screen_size_and_frustum_culls():
    s = lod.LodSettings(mesh_levels=((64.0, 0.0), (32.0, 0.05), (12.0, 0.1)), impostor_min_px=None,
                        point_levels=((6.0, 48, 0.3), (0.0, 16, 0.45)))
    px = np.array([500.0, 64.0, 63.0, 31.0, 8.0, 2.0, np.inf])
    levels = lod.choose_levels(px, s)
    assert levels.tolist() == [0, 0, 1, 2, 3, 4, 0]
    assert lod.shadow_levels(levels, s).tolist() == [1, 1, 2, 2, 3, 4, 1]
    # The default: the full mesh, impostors from 100 px down to 3 px, then points.
    d = lod.LodSettings()
    assert d.impostor_level == 1 and d.first_point_level == 2 and d.n_levels == 4
    levels = lod.choose_levels(np.array([500.0, 100.0, 99.0, 3.0, 2.9, 1.0]), d)
    assert levels.tolist() == [0, 0, 1, 1, 2, 3]
    assert lod.shadow_levels(levels, d).tolist() == [0, 0, 1, 1, 2, 3]
    assert lod.choose_levels(px, lod.LodSettings(enabled=False)).tolist() == [0] * 7
    view = np.eye(4)          # camera at the origin looking down -Z
    centres = np.array([[0, 0, -10.0], [0, 0, 10.0], [30, 0, -10.0], [7.5, 0, -10.0], [0, 0, -500.0]])
    vis = lod.in_frustum(centres, np.full(5, 1.0), view, 640 * 24 / 36, 640, 360, 0.1, 100)
    assert vis.tolist() == [True, False, False, True, False]


# ------------------------------------------------------------------ rendering
def test_srgb_encoding_matches_colour_science(gl):
    """The fragment shader's display transform against colour-science's."""
    import colour

    from usdcrowd.core.srgb import srgb8
    from usdcrowd.render.preview import shaders

    fs = shaders.VERSION + shaders.LIGHTING + """
    out vec4 o;
    void main() { o = vec4(srgb_encode(vec3((gl_FragCoord.x - 0.5) / 255.0)), 1.0); }"""
    vs = shaders.VERSION + "in vec2 p; void main() { gl_Position = vec4(p, 0.0, 1.0); }"
    prog = gl.program(vertex_shader=vs, fragment_shader=fs)
    vbo = gl.buffer(np.array([-1, -1, 3, -1, -1, 3], np.float32).tobytes())
    vao = gl.vertex_array(prog, [(vbo, "2f", "p")])
    fbo = gl.simple_framebuffer((256, 1))
    fbo.use()
    vao.render()
    got = np.frombuffer(fbo.read(components=3), np.uint8).reshape(256, 3)[:, 0].astype(int)
    want = np.round(colour.cctf_encoding(np.arange(256) / 255.0, function="sRGB") * 255).astype(int)
    assert np.abs(got - want).max() <= 1
    # The one sRGB encoder (core.srgb.srgb8) is colour-science's exactly.
    sweep = np.linspace(-0.1, 1.1, 100_001)
    exact = np.round(colour.cctf_encoding(np.clip(sweep, 0, 1), function="sRGB") * 255)
    assert np.array_equal(srgb8(sweep), exact.astype(np.uint8))


@pytest.mark.parametrize("name", ["preview_tiny.png", "preview_tiny_full.png"])
def test_render_matches_baseline(tiny_shot, name):
    from PIL import Image

    tool = _tool()
    baseline = np.asarray(Image.open(BASELINES / name).convert("RGB")).astype(int)
    frame = tool.render_tiny(tiny_shot, tool.BASELINE_NAMES[name])
    got = frame.color.astype(int)
    assert got.shape == baseline.shape
    bad = (np.abs(got - baseline) > PIXEL_TOLERANCE).any(-1)
    if bad.mean() > FAILING_FRACTION:
        FAILURES.mkdir(exist_ok=True)
        stem = FAILURES / name.replace(".png", "")
        Image.fromarray(frame.color).save(f"{stem}_actual.png")
        diff = np.clip(np.abs(got - baseline) * 4, 0, 255).astype(np.uint8)
        diff[bad] = (255, 0, 255)
        Image.fromarray(diff).save(f"{stem}_diff.png")
        pytest.fail(f"{bad.mean():.2%} of pixels differ by more than {PIXEL_TOLERANCE} "
                    f"(allowed {FAILING_FRACTION:.0%}); see {stem}_actual.png and {stem}_diff.png "
                    f"(regenerate with tools/make_preview_baselines.py if the change is deliberate)")


def test_ids_and_depth_agree_with_camera_project(exact_renderer):
    """Keypoints projected with CameraView.project land on their agent's pixels."""
    r = exact_renderer
    w, h = r.width, r.height
    for t in (1.0, 4.0, 6.0):
        f = r.render(t, "/World/Cam")
        poses = r.poses(t)
        boxes = f.boxes()
        kp = poses.keypoints()
        uv, z = f.camera.project(kp, w, h)
        checked = 0
        for i in np.flatnonzero(poses.visible):
            aid = int(poses.agent_ids[i])
            assert aid in boxes, f"agent {aid} missing from the id buffer at {t}"
            x0, y0, x1, y1 = boxes[aid]
            for k in range(3):          # pelvis, waist, neck: inside the body
                x, y = np.floor(uv[i, k]).astype(int)
                if f.ids[y, x] != aid and f.depth[y, x] < z[i, k] - 0.3:
                    continue            # hidden behind something nearer
                assert f.ids[y, x] == aid
                assert abs(f.depth[y, x] - z[i, k]) < 0.25       # the body's surface, in front of the joint
                checked += 1
            for k in (3, 4):            # head top and ground point: on the silhouette's edge
                x, y = uv[i, k]
                assert x0 - 1.5 <= x <= x1 + 1.5 and y0 - 1.5 <= y <= y1 + 1.5
        assert checked >= 9


def test_id_buffer_holds_scenery_ids_and_background(exact_renderer):
    r = exact_renderer
    f = r.render(4.0, "/World/Cam")
    ids = set(np.unique(f.ids).tolist())
    shape_ids = {s.shape_id for s in r.scene.scenery}
    assert shape_ids <= ids and min(shape_ids) >= SCENERY_ID_BASE
    assert 0 in ids and ids - shape_ids - {0} == {1, 2, 7, 12}
    assert np.isinf(f.depth[f.ids == 0]).all() and np.isfinite(f.depth[f.ids != 0]).all()
    assert f.color.dtype == np.uint8 and f.ids.dtype == np.uint32 and f.depth.dtype == np.float32
    # Background is the sky, characters are lit: not black, not one flat colour.
    assert f.color[f.ids == 0].std(0).max() < 1 and f.color[f.ids == 1].std(0).max() > 3


def test_characters_cast_shadows_on_the_floor(tiny_shot, gl):
    """Seed 003: the floor is darker beside each person, towards the sun's away side."""
    from usdcrowd.render.preview import LodSettings, PreviewRenderer

    with_shadows = PreviewRenderer(tiny_shot, 320, 180, ctx=gl, lod_settings=LodSettings(enabled=False))
    without = PreviewRenderer(tiny_shot, 320, 180, ctx=gl, lod_settings=LodSettings(enabled=False), shadows=False)
    try:
        a, b = with_shadows.render(4.0, "/World/Cam"), without.render(4.0, "/World/Cam")
        # A small image needs only part of the map: the shadows must still land right.
        assert 512 <= a.stats["shadow_texels"] < with_shadows.shadow_size
        assert b.stats["shadow_texels"] == 0
        floor_id = next(s.shape_id for s in with_shadows.scene.scenery if s.path.endswith("Floor"))
        floor = (a.ids == floor_id) & (b.ids == floor_id)
        darker = floor & (a.color.astype(int).sum(-1) < b.color.astype(int).sum(-1) - 30)
        assert darker.sum() > 40                     # four people's and a block's shadows
        # Each person's shadow touches their feet: darkened floor near every ground point.
        uv, _ = a.camera.project(with_shadows.poses(4.0).keypoints()[:, 4], 320, 180)
        ys, xs = np.nonzero(darker)
        for u, v in uv:
            assert (np.hypot(xs + 0.5 - u, ys + 0.5 - v) < 12).any()
    finally:
        with_shadows.release()
        without.release()


def test_clustered_shadow_mesh_casts_the_full_meshs_shadow(tiny_shot, gl):
    """Mesh-level characters cast with a coarser body: the shadow on the floor barely moves."""
    from usdcrowd.render.preview import LodSettings, PreviewRenderer

    frames, lit = {}, None
    for cell in (0.06, 0.0):
        r = PreviewRenderer(tiny_shot, 320, 180, ctx=gl, lod_settings=LodSettings(enabled=False, shadow_cell=cell))
        try:
            assert (r._shadow_mesh_vao is not None) == (cell > 0)
            frames[cell] = r.render(4.0, "/World/Cam")
            if lit is None:
                lit = PreviewRenderer(tiny_shot, 320, 180, ctx=gl, lod_settings=LodSettings(enabled=False),
                                      shadows=False)
                frames["lit"] = lit.render(4.0, "/World/Cam")
                lit.release()
        finally:
            r.release()
    floor_id = next(s.shape_id for s in r.scene.scenery if s.path.endswith("Floor"))
    bright = frames["lit"].color.astype(int).sum(-1)

    def shadowed(f):
        return (f.ids == floor_id) & (f.color.astype(int).sum(-1) < bright - 30)

    coarse, full = shadowed(frames[0.06]), shadowed(frames[0.0])
    assert full.sum() > 40
    # The same shadow to within a pixel of its outline (a 0.4 m grid already falls below 0.8).
    assert (coarse & full).sum() / (coarse | full).sum() > 0.95
    assert abs(int(coarse.sum()) - int(full.sum())) < 0.05 * full.sum()


def test_distant_characters_become_impostors_then_points_and_keep_their_ids(tiny_shot, gl):
    from usdcrowd.render.preview import PreviewRenderer

    r = PreviewRenderer(tiny_shot, 320, 180, ctx=gl)
    try:
        cam = r.scene.camera("/World/Cam", 4.0)

        def backed_off(metres):
            far = type(cam)(**{**cam.__dict__, "cam_to_world": cam.cam_to_world.copy()})
            far.cam_to_world[3, :3] += metres * far.cam_to_world[2, :3]     # back off along the view axis
            return far

        f = r.render(4.0, backed_off(25.0))
        assert f.stats["impostors"] == 4 and f.stats["full"] == 0
        assert set(f.boxes()) == {1, 2, 7, 12}
        # Without the impostor level the same characters are seed 004's points.
        r_points = PreviewRenderer(tiny_shot, 320, 180, ctx=gl, lod_settings=lod.LodSettings(
            impostor_min_px=None, point_levels=((6.0, 48, 0.3), (0.0, 16, 0.45))))
        try:
            g = r_points.render(4.0, backed_off(25.0))
            assert g.stats["points"] == 4 and g.stats["impostors"] == 0
            assert set(g.boxes()) == {1, 2, 7, 12}
        finally:
            r_points.release()
        # Behind the camera: culled.
        behind = type(cam)(**{**cam.__dict__, "cam_to_world": np.diag([-1.0, 1, -1, 1]) @ cam.cam_to_world})
        assert r.render(4.0, behind).stats["culled"] == 4
    finally:
        r.release()


def test_shadow_casters_go_nearest_the_sun_first_and_the_frame_does_not_depend_on_it(tiny_shot, gl, monkeypatch):
    """The order only saves work (the map's early depth test): every pixel, id and depth stays."""
    from usdcrowd.render.preview import PreviewRenderer
    from usdcrowd.render.preview import renderer as renderer_module

    r = PreviewRenderer(tiny_shot, 320, 180, ctx=gl)
    try:
        cam = r.scene.camera("/World/Cam", 4.0)
        poses = r.poses(4.0)
        plan = r._plan(poses, cam, cam.world_to_cam, float(cam.intrinsics(320, 180)[0, 0]))
        casters = plan["s_order"]
        assert len(casters) == 4
        toward_sun = plan["centres"][casters] @ r.lights.sun_dir
        assert (np.diff(toward_sun) <= 0).all()
        ordered = r.render_poses(poses, cam)

        group_by_level = lod.group_by_level

        def unordered(levels, visible, n_levels, distance=None):
            return group_by_level(levels, visible, n_levels,
                                      None if distance is None else -np.asarray(distance))
        monkeypatch.setattr(renderer_module.lod, "group_by_level", unordered)
        reverse = r.render_poses(poses, cam)
        assert r._plan(poses, cam, cam.world_to_cam, float(cam.intrinsics(320, 180)[0, 0]))["s_order"].tolist() \
            == casters[::-1].tolist()
        for a, b in zip(ordered, reverse):        # colour, ids, depth
            np.testing.assert_array_equal(a, b)
    finally:
        r.release()


def test_overlays_draw_over_colour_only(tiny_shot, gl):
    from usdcrowd.render.preview import PreviewRenderer
    from usdcrowd.render.preview.overlays import Overlays

    from usdcrowd.scenario.shot_scene import ShotScene

    scene = ShotScene(tiny_shot)
    plain = PreviewRenderer(scene, 320, 180, ctx=gl)
    marked = PreviewRenderer(scene, 320, 180, ctx=gl, overlays=Overlays(scene, ["trajectories", "ids", "frusta"]))
    try:
        a, b = plain.render(4.0, "/World/Cam"), marked.render(4.0, "/World/Cam")
        assert (a.ids == b.ids).all() and np.array_equal(a.depth, b.depth)
        assert (a.color != b.color).any(-1).sum() > 100
    finally:
        plain.release()
        marked.release()


# ----------------------------------------------------------------- outputs
def test_cli_writes_frames_aovs_video_and_sheet(tiny_shot, tmp_path, capsys):
    from PIL import Image

    from usdcrowd.cli import main

    frames = tmp_path / "frames"
    assert main(["preview", str(tiny_shot), "-o", str(frames), "--frames", "1:3", "--resolution", "160x90",
                 "--camera", "/World/Cam", "--aovs", "--no-progress"]) == 0
    assert sorted(p.name for p in frames.glob("frame.*.png")) == ["frame.0001.png", "frame.0002.png",
                                                                  "frame.0003.png"]
    aov = np.load(frames / "frame.0002.npz")
    assert aov["ids"].dtype == np.uint32 and aov["ids"].shape == (90, 160)
    with Image.open(frames / "contact_sheet.png") as sheet:
        assert sheet.size[0] > 160
    video = tmp_path / "p.mp4"
    assert main(["preview", str(tiny_shot), "-o", str(video), "--resolution", "160x90", "--no-progress",
                 "--overlays", "all"]) == 0
    assert video.stat().st_size > 1000 and (tmp_path / "p_sheet.png").exists()
    import imageio.v3 as iio

    assert iio.imread(video, index=None).shape[0] == 6       # the stage's six frames


def test_cli_reports_a_wrong_camera_in_one_line(tiny_shot, tmp_path, capsys):
    from usdcrowd.cli import main

    assert main(["preview", str(tiny_shot), "-o", str(tmp_path / "x.mp4"), "--camera", "/World/Nope"]) == 2
    err = capsys.readouterr().err.strip()
    assert "not a camera" in err and "\n" not in err
    assert main(["preview", str(tiny_shot), "-o", str(tmp_path / "y"), "--overlays", "sparkles"]) == 2


def test_preview_outputs_write_a_video_and_a_contact_sheet(tiny_shot, tmp_path):
    from usdcrowd.render.demo import preview_outputs

    paths = preview_outputs(tiny_shot, tmp_path / "demo", camera="/World/Cam", resolution=(160, 90))
    assert set(paths) == {"mp4", "contact_sheet"}
    assert all(Path(p).stat().st_size > 0 for p in paths.values())


WINDOW_SCRIPT = """
import sys, glfw
import usdcrowd
from usdcrowd.scenario.shot_scene import ShotScene
from usdcrowd.render.preview.window import run_viewer
scene = ShotScene(sys.argv[1])
keys = ((2, glfw.KEY_SPACE), (3, glfw.KEY_RIGHT), (4, glfw.KEY_F), (5, glfw.KEY_W), (6, glfw.KEY_C))
sys.exit(run_viewer(scene, 160, 90, max_frames=8, keys=keys, screenshot=sys.argv[2]))
"""


def test_window_plays_under_a_virtual_display(tiny_shot, tmp_path):
    """The glfw path, under Xvfb (apt-get install xvfb) where it is installed."""
    import shutil
    import subprocess
    import sys

    from PIL import Image

    if shutil.which("xvfb-run") is None:
        pytest.skip("xvfb-run not installed (apt-get install xvfb)")
    shot_png = tmp_path / "window.png"
    proc = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 640x480x24", sys.executable, "-c", WINDOW_SCRIPT,
                           str(tiny_shot), str(shot_png)], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr[-2000:]
    img = np.asarray(Image.open(shot_png))
    from usdcrowd.render.preview.window import SCRUB_PX

    assert img.shape == (90 + SCRUB_PX, 160, 3)
    assert img[:90].std() > 10                      # a picture, not a cleared screen


def test_no_display_is_one_clear_error(tiny_shot, monkeypatch):
    from usdcrowd.core.errors import UsdcrowdError
    from usdcrowd.render.preview.context import window_context

    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(UsdcrowdError, match="no display"):
        window_context(100, 100)


def test_impostors_stand_where_the_meshes_do(tiny_shot, gl):
    """Per-joint impostors: same place, size and shading as the mesh they replace, within a preview's tolerance."""
    from usdcrowd.render.preview import PreviewRenderer

    settings = {"impostors": lod.LodSettings(mesh_levels=((1e9, 0.0),)),   # everyone an impostor
                "meshes": lod.LodSettings(enabled=False)}
    frames = {}
    for name, s in settings.items():
        r = PreviewRenderer(tiny_shot, 640, 360, ctx=gl, lod_settings=s)
        try:
            frames[name] = r.render(4.0, "/World/Cam")
        finally:
            r.release()
    imp, mesh = frames["impostors"], frames["meshes"]
    assert imp.stats["impostors"] == 4 and mesh.stats["full"] == 4
    bi, bm = imp.boxes(), mesh.boxes()
    assert set(bi) == set(bm) == {1, 2, 7, 12}
    for k in bm:
        a, b = bi[k], bm[k]
        ix = max(0, min(a[2], b[2]) - max(a[0], b[0]))
        iy = max(0, min(a[3], b[3]) - max(a[1], b[1]))
        inter = ix * iy
        iou = inter / ((a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter)
        assert iou > 0.75, (k, a, b)
        n_imp, n_mesh = (imp.ids == k).sum(), (mesh.ids == k).sum()
        assert abs(n_imp / n_mesh - 1.0) < 0.25, (k, n_imp, n_mesh)
        # Lit like the mesh: mean colour of the agent's pixels within 12 code values.
        c_imp = imp.color[imp.ids == k].mean(0)
        c_mesh = mesh.color[mesh.ids == k].mean(0)
        assert np.abs(c_imp - c_mesh).max() < 12, (k, c_imp, c_mesh)


@pytest.fixture(scope="module")
def walled_shot(tmp_path_factory, gl):
    """The tiny shot with its block made a thin wall: 3 m long across y = 1.5, 0.15 m thick, 1.2 m tall."""
    tool = _tool()
    stage = tool.TINY_STAGE.replace("xformOp:translate = (2.5, 1.5, 0.75)", "xformOp:translate = (2.5, 1.5, 0.6)")
    stage = stage.replace("xformOp:scale = (1.2, 1.2, 1.5)", "xformOp:scale = (3, 0.15, 1.2)")
    assert stage.count("(3, 0.15, 1.2)") == 1 and "(2.5, 1.5, 0.6)" in stage
    return tool.make_tiny_shot(tmp_path_factory.mktemp("walled"), stage)


def test_an_impostor_just_behind_a_wall_stays_behind_it(walled_shot, gl):
    """Seen from above, an impostor's quad leans toward the camera: the legs of someone standing just
    behind a thin wall came through it. Its depth now keeps them hidden, as the mesh's are."""
    from dataclasses import replace

    from usdcrowd.core.view import look_at
    from usdcrowd.render.preview import PreviewRenderer

    renderers = {"impostor": PreviewRenderer(walled_shot, 640, 360, ctx=gl, lod_settings=lod.LodSettings(
        mesh_levels=((1e9, 0.0),))), "mesh": PreviewRenderer(walled_shot, 640, 360, ctx=gl,
                                                              lod_settings=lod.LodSettings(enabled=False))}
    try:
        mesh_r = renderers["mesh"]
        poses = mesh_r.poses(4.0)
        wall = next(s.shape_id for s in mesh_r.scene.scenery if s.path.endswith("Block"))
        # Agent 1 alone, 0.3 m behind the wall's far face (its body's nearest point about 0.1 m from it).
        joints = poses.joints_world.copy()
        joints[0, :, 3, :2] += np.array([2.5, 1.875]) - joints[0, 0, 3, :2]
        alone = replace(poses, joints_world=joints, visible=np.arange(len(poses)) == 0)
        base = mesh_r.scene.camera("/World/Cam", 4.0)
        target = np.array([2.5, 1.875, 0.9])
        for elevation in (30.0, 45.0, 60.0):
            e = np.radians(elevation)
            back = np.array([0.0, -np.cos(e), np.sin(e)])           # from the agent toward the camera
            cam = replace(base, cam_to_world=look_at(target + 8.0 * back, target)[0])
            imp, mesh = (renderers[k].render_poses(alone, cam) for k in ("impostor", "mesh"))
            assert imp.stats["impostors"] == 1 and mesh.stats["full"] == 1
            shown = imp.ids == 1
            assert shown.sum() > 100 and (mesh.ids == 1).sum() > 100, elevation   # head and shoulders
            through = shown & (mesh.ids == wall)
            assert through.sum() <= 0.02 * shown.sum(), (elevation, int(through.sum()), int(shown.sum()))
    finally:
        for r in renderers.values():
            r.release()


def test_an_impostor_in_a_blocks_shadow_is_as_dark_as_its_mesh(tiny_shot, gl):
    """The sun's visibility reaches impostors: one stood in the block's shadow darkens as its mesh does."""
    from dataclasses import replace

    from usdcrowd.render.preview import PreviewRenderer

    renderers = {"impostor": PreviewRenderer(tiny_shot, 640, 360, ctx=gl, lod_settings=lod.LodSettings(
        mesh_levels=((1e9, 0.0),))), "mesh": PreviewRenderer(tiny_shot, 640, 360, ctx=gl,
                                                              lod_settings=lod.LodSettings(enabled=False))}
    try:
        poses = renderers["mesh"].poses(4.0)
        cam = renderers["mesh"].scene.camera("/World/Cam", 4.0)
        sun = renderers["mesh"].lights.sun_dir
        away = -sun[:2] / np.linalg.norm(sun[:2])
        block = np.array([2.5, 1.5])
        colours = {}
        # Agent 1 stood behind the block from the sun (its shadow covers the legs), then in the open.
        for where, distance in (("shade", 1.0), ("sun", 3.0)):
            joints = poses.joints_world.copy()
            joints[0, :, 3, :2] += block + distance * away - joints[0, 0, 3, :2]
            moved = replace(poses, joints_world=joints)
            for name, r in renderers.items():
                f = r.render_poses(moved, cam)
                colours[where, name] = f.color[f.ids == 1].astype(float).mean(0)
        # The mesh is clearly darker in the shade; the impostor follows it within a preview's tolerance.
        assert (colours["sun", "mesh"] - colours["shade", "mesh"]).mean() > 8, colours
        for where in ("shade", "sun"):
            assert np.abs(colours[where, "impostor"] - colours[where, "mesh"]).max() < 12, (where, colours)
    finally:
        for r in renderers.values():
            r.release()


def test_impostors_cast_the_shadows_their_meshes_cast(tiny_shot, gl):
    """Characters drawn as impostors cast their shadows on the floor where their meshes do (the sun's
    pictures are placed for the sun's view, not the camera's)."""
    from usdcrowd.render.preview import PreviewRenderer

    settings = {"impostor": lod.LodSettings(mesh_levels=((1e9, 0.0),)), "mesh": lod.LodSettings(enabled=False)}
    frames = {}
    for name, s in settings.items():
        for shadows in (True, False):
            r = PreviewRenderer(tiny_shot, 320, 180, ctx=gl, lod_settings=s, shadows=shadows)
            try:
                frames[name, shadows] = r.render(4.0, "/World/Cam")
            finally:
                r.release()
    assert frames["impostor", True].stats["impostors"] == 4 and frames["mesh", True].stats["full"] == 4
    floor_id = next(s.shape_id for s in r.scene.scenery if s.path.endswith("Floor"))

    def shadowed(name):
        a, b = frames[name, True], frames[name, False]
        floor = (a.ids == floor_id) & (b.ids == floor_id)
        return floor & (a.color.astype(int).sum(-1) < b.color.astype(int).sum(-1) - 30)

    imp, mesh = shadowed("impostor"), shadowed("mesh")
    assert mesh.sum() > 40
    assert (imp & mesh).sum() / (imp | mesh).sum() > 0.85, (int(imp.sum()), int(mesh.sum()), int((imp & mesh).sum()))
