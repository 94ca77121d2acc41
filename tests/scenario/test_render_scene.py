"""The per-frame scene both renderers read: skinning, cameras, scenery, lights."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Usd, UsdSkel

from tests.helpers.frames import straight_walk
from usdcrowd.core.errors import StageError
from usdcrowd.jobs.pipeline import author_shot
from usdcrowd.core.geometry import triangulate
from usdcrowd.scenario.shot_scene import SCENERY_ID_BASE, ShotScene, color_temperature_rgb


@pytest.fixture(scope="module")
def museum_scene(tmp_path_factory):
    """The museum shot with straight-walking agents, opened for rendering."""
    import usdcrowd.core.resources as res

    out = tmp_path_factory.mktemp("shot")
    r = author_shot(res.data_dir("stages") / "museum.usda", out, lambda sc: [straight_walk(sc.agents, sc.time)],
                    frames=(1, 12), progress=False)
    return ShotScene(r.shot)


def test_agents_skin_exactly_as_usdskel(museum_scene):
    poses = museum_scene.agents(7)
    verts = museum_scene.skinned_vertices(poses)
    stage = museum_scene.stage
    for i in (0, 5, 12):
        cache = UsdSkel.Cache()
        root = UsdSkel.Root(stage.GetPrimAtPath(poses.paths[i]))
        cache.Populate(root, Usd.TraverseInstanceProxies())
        (binding,) = cache.ComputeSkelBindings(root, Usd.TraverseInstanceProxies())
        (target,) = binding.GetSkinningTargets()
        pts = target.GetPrim().GetAttribute("points").Get(7)
        target.ComputeSkinnedPoints(cache.GetSkelQuery(binding.GetSkeleton()).ComputeSkinningTransforms(7), pts, 7)
        assert np.abs(np.array(pts) - verts[i]).max() < 1e-5


def test_invisible_leader_is_marked_and_ids_are_track_ids(museum_scene):
    poses = museum_scene.agents(1)
    guide = poses.paths.index("/World/Crowd/Visitors/Family/Guide")
    assert not poses.visible[guide] and poses.visible.sum() == len(poses) - 1
    assert sorted(poses.agent_ids) == list(range(100, 119))


def test_camera_projects_a_point_on_its_axis_to_the_image_centre(museum_scene):
    cam = museum_scene.camera("/World/Cameras/Overview", 1)
    ahead = cam.position - 10.0 * cam.cam_to_world[2, :3]         # 10 m down the view axis (-Z)
    uv, z = cam.project(ahead[None], 640, 360)
    assert np.allclose(uv[0], (320, 180)) and z[0] == pytest.approx(10.0)
    assert cam.fov_x() == pytest.approx(np.degrees(2 * np.arctan(18 / 24)))
    with pytest.raises(StageError, match="not a camera"):
        museum_scene.camera("/World/Scenery/Floor", 1)


def test_scenery_has_world_geometry_ids_and_colours(museum_scene):
    by_name = {s.path.rsplit("/", 1)[-1]: s for s in museum_scene.scenery}
    wall = by_name["WallNorth"]
    v = np.hstack([wall.mesh.vertices, np.ones((len(wall.mesh.vertices), 1))]) @ wall.local_to_world(1)
    assert np.allclose(v[:, :3].min(0), (-15, 9.85, 0)) and np.allclose(v[:, :3].max(0), (15, 10.15, 3))
    assert np.allclose(wall.material.base_color, (0.85, 0.83, 0.8))
    assert all(s.shape_id >= SCENERY_ID_BASE for s in museum_scene.scenery)
    assert len({s.shape_id for s in museum_scene.scenery}) == len(museum_scene.scenery)


def test_lights_and_colour_temperature(museum_scene):
    kinds = {l.kind for l in museum_scene.lights}
    assert kinds == {"distant", "dome", "sphere"}
    lamp = next(l for l in museum_scene.lights if l.kind == "sphere")
    assert lamp.radius == pytest.approx(0.2) and lamp.rgb[0] > lamp.rgb[2]      # 3200 K is warm
    # A black body at 6504 K sits near, not on, D65: UsdLux tints along the Planckian locus.
    assert np.allclose(color_temperature_rgb(6504), (1, 1, 1), atol=0.06)


def test_triangulate_fans():
    tris = triangulate([4, 3], [0, 1, 2, 3, 4, 5, 6])
    assert tris.tolist() == [[0, 1, 2], [0, 2, 3], [4, 5, 6]]
