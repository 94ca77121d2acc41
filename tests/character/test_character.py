"""Character rig, body and animation; skinning checked against UsdSkel."""

import numpy as np
import pytest

import usdcrowd  # noqa: F401  (registers the crowd schemas before any stage)
from usdcrowd.character import (BIND_SKEL, JOINTS, REST_LOCAL, advance_phase, apply_look_at,
                                blend_transitions, build_body, classify, compose_local,
                                head_forward, keypoints, local_to_skel, pose, quat_angle,
                                quat_from_axis_angle, quat_multiply, quat_slerp, quat_to_matrix,
                                skin_points, skinning_transforms, to_usd_quat_order)
from usdcrowd.character import animate as animate_frames
from usdcrowd.character.animation import EYE_HEIGHT, HEAD_TOP
from usdcrowd.core.model import ANIM_CLASSES

DT = 1.0 / 24.0
IDLE, WALK, RUN, LEFT, RIGHT = range(5)
# Largest rotation any joint may make between two frames at 24 fps: 20 deg
# (480 deg/s) clears a 4.5 m/s run cycle (~14 deg) but not a class switch.
MAX_DEG_PER_FRAME = 20.0


# ----------------------------------------------------------------- body

def test_body():
    b = build_body()
    assert b is build_body()
    assert b.mesh.is_watertight and b.mesh.is_winding_consistent
    assert 500 <= b.triangle_count <= 2000
    lo, hi = b.points.min(0), b.points.max(0)
    assert abs(hi[2] - 1.75) < 0.01 and abs(lo[2]) < 1e-6
    assert hi[0] > -lo[0]  # feet and nose stick out toward +X
    assert b.points.dtype == np.float32 and b.joint_weights.dtype == np.float32
    assert b.face_vertex_indices.dtype == np.int32 and b.joint_indices.dtype == np.int32
    assert len(b.face_vertex_indices) == 3 * b.triangle_count
    assert b.face_vertex_indices.max() < len(b.points)
    assert b.joint_indices.shape == b.joint_weights.shape == (len(b.points), 2)
    np.testing.assert_allclose(b.joint_weights.sum(1), 1.0, atol=1e-6)
    assert (np.diff(b.joint_weights, axis=1) <= 0).all()
    assert b.joint_indices.min() >= 0 and b.joint_indices.max() < len(JOINTS)
    assert set(np.unique(b.joint_indices[:, 0])) == {0, 1, 2}
    assert np.allclose(np.linalg.norm(b.normals, axis=1), 1.0, atol=1e-4)


# ----------------------------------------------------------------- rig maths

def test_quaternions_and_rig():
    rng = np.random.default_rng(1)
    q = rng.normal(size=(5, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    r = rng.normal(size=(5, 4))
    r /= np.linalg.norm(r, axis=1, keepdims=True)
    # Row convention: v @ R(a*b) == (v @ R(b)) @ R(a).
    np.testing.assert_allclose(quat_to_matrix(quat_multiply(q, r)),
                               quat_to_matrix(r) @ quat_to_matrix(q), atol=1e-12)
    z90 = quat_from_axis_angle([0, 0, 1], np.pi / 2)
    np.testing.assert_allclose(np.array([1.0, 0, 0]) @ quat_to_matrix(z90), [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(quat_slerp(q, r, 0.0), q, atol=1e-12)
    assert np.allclose(np.abs(np.sum(quat_slerp(q, r, 1.0) * r, -1)), 1.0)
    np.testing.assert_allclose(quat_angle(q, quat_slerp(q, r, 0.25)), 0.25 * quat_angle(q, r),
                               atol=1e-9)
    np.testing.assert_allclose(quat_angle(q, -q), 0.0, atol=1e-6)
    np.testing.assert_allclose(REST_LOCAL, compose_local(np.tile([1.0, 0, 0, 0], (3, 1)),
                                                         REST_LOCAL[:, 3, :3]))
    np.testing.assert_allclose(skinning_transforms(BIND_SKEL), np.tile(np.eye(4), (3, 1, 1)),
                               atol=1e-12)
    kp = keypoints(BIND_SKEL)
    np.testing.assert_allclose(kp[3], [0, 0, 1.75])
    np.testing.assert_allclose(kp[4], [0, 0, 0])


def test_usd_quat_order():
    from pxr import Gf, Vt
    q = np.array([[0.5, 0.1, 0.2, 0.3], [1.0, 0.0, 0.0, 0.0]], np.float32)  # (w, x, y, z)
    # Vt.QuatfArray.FromNumpy reads rows as (x, y, z, w): GfQuatf keeps its
    # imaginary part first in memory, unlike the Gf.Quatf(w, x, y, z) constructor.
    usd = Vt.QuatfArray.FromNumpy(to_usd_quat_order(q))
    assert usd[0] == Gf.Quatf(0.5, 0.1, 0.2, 0.3) and usd[1] == Gf.Quatf(1, 0, 0, 0)
    assert usd[0].GetReal() == pytest.approx(0.5)
    # quat_to_matrix is the row-vector block Gf builds from the same quaternion.
    qd = q[0] / np.linalg.norm(q[0])
    gf = Gf.Matrix4d().SetRotate(Gf.Quatd(*map(float, qd)))
    np.testing.assert_allclose(np.array(gf)[:3, :3], quat_to_matrix(qd), atol=1e-6)
    np.testing.assert_array_equal(to_usd_quat_order(q[None]), np.array(usd)[None])


# ----------------------------------------------------------------- UsdSkel

def _sample_poses():
    """(k, 3, 4) float32 rotations and (k, 3, 3) translations over classes and phases."""
    cls = np.array([IDLE, WALK, WALK, RUN, RUN, LEFT, RIGHT, WALK])
    phase = np.array([0.3, 0.1, 0.6, 0.25, 0.8, 0.4, 0.9, 0.2])
    speed = np.array([0.0, 1.4, 1.4, 4.0, 4.0, 1.0, 1.0, 1.2])
    rot, tr = pose(cls, phase, speed)
    # The last pose also looks at a point up and to the left.
    target = np.full((1, len(cls), 3), np.nan)
    target[0, -1] = [2.0, 3.0, 2.5]
    rot = apply_look_at(rot[None], np.zeros((1, len(cls), 3)), np.zeros((1, len(cls))),
                        1.75, target)[0]
    return rot.astype(np.float32), tr.astype(np.float32)


def test_skinning_matches_usdskel():
    from pxr import Gf, Usd, UsdGeom, UsdSkel, Vt
    body = build_body()
    rot, tr = _sample_poses()
    geom_bind = np.eye(4)
    geom_bind[3, :3] = [0.1, -0.05, 0.02]  # mesh authored offset, undone by the bind
    mesh_points = (body.points - geom_bind[3, :3]).astype(np.float32)

    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    root = UsdSkel.Root.Define(stage, "/Agent")
    skel = UsdSkel.Skeleton.Define(stage, "/Agent/Skel")
    skel.CreateJointsAttr(list(JOINTS))
    skel.CreateBindTransformsAttr(Vt.Matrix4dArray.FromNumpy(BIND_SKEL))
    skel.CreateRestTransformsAttr(Vt.Matrix4dArray.FromNumpy(REST_LOCAL))
    anim = UsdSkel.Animation.Define(stage, "/Agent/Skel/Anim")
    anim.CreateJointsAttr(list(JOINTS))
    anim.CreateScalesAttr(Vt.Vec3hArray([Gf.Vec3h(1, 1, 1)] * 3))
    rot_attr, tr_attr = anim.CreateRotationsAttr(), anim.CreateTranslationsAttr()
    for t in range(len(rot)):
        rot_attr.Set(Vt.QuatfArray.FromNumpy(to_usd_quat_order(rot[t])), t)
        tr_attr.Set(Vt.Vec3fArray.FromNumpy(tr[t]), t)
    UsdSkel.BindingAPI.Apply(skel.GetPrim()).CreateAnimationSourceRel().SetTargets(
        [anim.GetPath()])
    mesh = UsdGeom.Mesh.Define(stage, "/Agent/Body")
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(mesh_points))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(body.face_vertex_counts))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(body.face_vertex_indices))
    binding = UsdSkel.BindingAPI.Apply(mesh.GetPrim())
    binding.CreateSkeletonRel().SetTargets([skel.GetPath()])
    binding.CreateJointIndicesPrimvar(False, 2).Set(Vt.IntArray.FromNumpy(body.joint_indices.ravel()))
    binding.CreateJointWeightsPrimvar(False, 2).Set(
        Vt.FloatArray.FromNumpy(body.joint_weights.ravel()))
    binding.CreateGeomBindTransformAttr(Gf.Matrix4d(*geom_bind.ravel()))

    cache = UsdSkel.Cache()
    cache.Populate(root, Usd.TraverseInstanceProxies())
    skel_query = cache.GetSkelQuery(skel)
    (skel_binding,) = cache.ComputeSkelBindings(root, Usd.TraverseInstanceProxies())
    (skinning_query,) = skel_binding.GetSkinningTargets()

    ours = skinning_transforms(local_to_skel(compose_local(rot, tr)))
    ours_points = skin_points(mesh_points, body.joint_indices, body.joint_weights, ours, geom_bind)
    err_xf, err_pts = 0.0, 0.0
    for t in range(len(rot)):
        xforms = skel_query.ComputeSkinningTransforms(t)
        err_xf = max(err_xf, np.abs(np.array(xforms) - ours[t]).max())
        pts = Vt.Vec3fArray.FromNumpy(mesh_points)
        assert skinning_query.ComputeSkinnedPoints(xforms, pts, t)
        err_pts = max(err_pts, np.abs(np.array(pts) - ours_points[t]).max())
    print(f"max error vs UsdSkel: transforms {err_xf:.2e}, points {err_pts:.2e} m")
    assert err_xf < 1e-5 and err_pts < 1e-5, (err_xf, err_pts)
    # The poses really moved the body (the comparison is not vacuous).
    assert np.abs(ours_points - body.points).max() > 0.1


# ----------------------------------------------------------------- animation

def test_classify():
    v = np.array([[[0.05, 0.0], [1.0, 0.2], [3.0, 0.0], [0.1, 1.0], [0.2, -1.0],
                   [0.0, 1.0], [-1.2, 0.0]]])
    heading = np.array([[0.0, 0.0, 0.0, 0.0, 0.0, np.pi / 2, 0.0]])
    got = classify(v, heading)
    assert got.dtype == np.int8
    names = [ANIM_CLASSES[c] for c in got[0]]
    assert names == ["idle", "walk", "run", "strideLeft", "strideRight", "walk", "walk"]


def test_phase():
    t = 200
    speed = np.tile(np.array([0.0, 1.4, 4.0, 1.0]), (t, 1))
    speed[100:, 1] = 3.0  # walk -> run mid-way
    cls = np.tile(np.array([IDLE, WALK, RUN, LEFT]), (t, 1))
    cls[100:, 1] = RUN
    ph = advance_phase(speed, cls, DT, phase0=np.array([0.0, 0.5, 0.99, 0.2]))
    assert ph.dtype == np.float32 and ph.shape == (t, 4)
    assert (ph >= 0).all() and (ph < 1).all()
    np.testing.assert_allclose(ph[0], [0.0, 0.5, 0.99, 0.2], atol=1e-6)
    step = np.mod(np.diff(ph, axis=0), 1.0)
    assert (step > 0).all() and (step < 0.2).all()  # monotonic, no skipped cycles
    # About 1 walk cycle per 1.4 m.
    assert step[:99, 1].sum() / (99 * DT * 1.4) == pytest.approx(1 / 1.4, rel=0.2)


def _switching_sequence():
    seg = [(WALK, 1.4, 30), (RUN, 4.5, 29), (LEFT, 1.2, 25), (RIGHT, 1.2, 25),
           (RUN, 4.5, 27), (IDLE, 0.0, 20), (RUN, 4.5, 20), (WALK, 1.4, 20)]
    cls = np.concatenate([np.full(f, c) for c, _, f in seg])
    speed = np.concatenate([np.full(f, s) for _, s, f in seg])
    # Two agents, the second shifted so that switches fall on other phases.
    cls = np.stack([cls, np.roll(cls, 7)], 1)
    speed = np.stack([speed, np.roll(speed, 7)], 1)
    ph = advance_phase(speed, cls, DT)
    return cls, ph, speed


def _max_step_deg(rot):
    return np.degrees(quat_angle(rot[1:], rot[:-1])).max()


def test_blending_bounds_joint_speed():
    cls, ph, speed = _switching_sequence()
    rot, tr = pose(cls, ph, speed)
    assert _max_step_deg(rot) > MAX_DEG_PER_FRAME  # raw switches jump
    brot, btr = blend_transitions(cls, rot, tr)
    assert _max_step_deg(brot) < MAX_DEG_PER_FRAME
    assert np.abs(np.diff(btr, axis=0)).max() < np.abs(np.diff(tr, axis=0)).max()
    # Blending only touches the frames right after a switch.
    settled = np.ones_like(cls, dtype=bool)
    for k in range(1, 7):
        settled[k:] &= cls[k:] == cls[:-k]
    np.testing.assert_allclose(brot[settled], rot[settled], atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(brot, axis=-1), 1.0, atol=1e-9)


def test_look_at_aims_head():
    rng = np.random.default_rng(3)
    t, n = 4, 6
    cls = rng.integers(0, 5, size=(t, n))
    rot, _ = pose(cls, rng.random((t, n)), np.full((t, n), 1.2))
    position = rng.uniform(-5, 5, size=(t, n, 3)) * [1, 1, 0]
    heading = rng.uniform(-np.pi, np.pi, size=(t, n))
    height = rng.uniform(1.5, 1.9, size=n)
    eye = position + np.stack([0 * heading, 0 * heading, EYE_HEIGHT / HEAD_TOP * height + 0 * heading], -1)
    # Targets within the limits: 50 deg to either side, 20 deg up or down.
    yaw = heading + rng.uniform(-np.radians(50), np.radians(50), size=(t, n))
    pitch = rng.uniform(-np.radians(20), np.radians(20), size=(t, n))
    d = np.stack([np.cos(pitch) * np.cos(yaw), np.cos(pitch) * np.sin(yaw), np.sin(pitch)], -1)
    target = eye + 4.0 * d
    target[0, 0] = np.nan  # no target: pose untouched
    out = apply_look_at(rot, position, heading, height, target)
    np.testing.assert_allclose(out[..., 0, :], rot[..., 0, :])  # legs untouched
    np.testing.assert_allclose(out[0, 0], rot[0, 0])
    # Head forward in world = skeleton forward turned by the heading.
    f = head_forward(out)
    c, s = np.cos(heading), np.sin(heading)
    world = np.stack([c * f[..., 0] - s * f[..., 1], s * f[..., 0] + c * f[..., 1], f[..., 2]], -1)
    cos = np.sum(world * d, -1)[np.isfinite(target[..., 0])]
    assert np.degrees(np.arccos(np.clip(cos, -1, 1))).max() < 0.1
    # Beyond the limits the head stops at 70 deg.
    behind = eye - 4.0 * np.stack([np.cos(heading - 0.3), np.sin(heading - 0.3), 0 * heading], -1)
    f = head_forward(apply_look_at(rot, position, heading, height, behind))
    assert np.allclose(np.degrees(np.abs(np.arctan2(f[..., 1], f[..., 0]))), 70.0, atol=0.5)


def test_look_at_rate_limited():
    t, n = 40, 1
    rot, _ = pose(np.full((t, n), WALK), np.linspace(0, 2, t)[:, None] % 1, np.full((t, n), 1.4))
    target = np.full((t, n, 3), np.nan)
    target[5:25] = [0.0, 10.0, 1.63]  # 90 deg to the left, clamped to 70
    out = apply_look_at(rot, np.zeros((t, n, 3)), np.zeros((t, n)), 1.75, target,
                        max_step=np.radians(10))
    assert _max_step_deg(out) < MAX_DEG_PER_FRAME
    yaw = np.degrees(np.arctan2(*head_forward(out)[..., 0, 1::-1].T))
    assert abs(yaw[20] - 70) < 1 and abs(yaw[-1]) < 5


def _switching_frames():
    from usdcrowd.core.model import CrowdFrames
    cls, ph, speed = _switching_sequence()
    t, n = cls.shape
    heading = np.zeros((t, n), np.float32)
    velocity = np.stack([speed, 0 * speed], -1).astype(np.float32)
    look = np.full((t, n, 3), np.nan, np.float32)
    look[50:120, 0] = [5.0, 5.0, 1.0]
    look[90:160, 1] = [-3.0, 4.0, 2.0]
    return CrowdFrames(times=np.arange(t, dtype=np.float64), position=np.zeros((t, n, 3), np.float32),
                       heading=heading, velocity=velocity, behavior=np.zeros((t, n), np.int8),
                       anim_class=cls.astype(np.int8), anim_phase=ph,
                       health=np.zeros((t, n), np.int8), look_at=look,
                       path_method=np.zeros(n, np.int8))


def test_animate_crowd_frames():
    frames = _switching_frames()
    t, n = frames.anim_class.shape
    rot, tr = animate_frames(frames, DT, np.array([1.75, 1.6]))
    assert rot.dtype == tr.dtype == np.float32
    assert rot.shape == (t, n, 3, 4) and tr.shape == (t, n, 3, 3)
    assert _max_step_deg(rot.astype(np.float64)) < MAX_DEG_PER_FRAME
    f = head_forward(rot[100, 0])
    assert np.degrees(np.arctan2(f[1], f[0])) == pytest.approx(45.0, abs=1.0)


@pytest.mark.parametrize("cuts", [(1,), (7, 51, 52, 95, 130), tuple(range(3, 200, 11))])
def test_animation_independent_of_chunks(cuts):
    """Blends and head turns carry over chunk boundaries: cutting a shot changes nothing."""
    from usdcrowd.character.animation import Animator
    frames = _switching_frames()
    height = np.array([1.75, 1.6])
    whole_rot, whole_tr = animate_frames(frames, DT, height)
    animator = Animator(DT, height)
    bounds = [0, *[c for c in cuts if c < len(frames.times)], len(frames.times)]
    parts = []
    for a, b in zip(bounds[:-1], bounds[1:]):
        parts.append(animator(frames.frames(slice(a, b))))
    np.testing.assert_array_equal(np.concatenate([p[0] for p in parts]), whole_rot)
    np.testing.assert_array_equal(np.concatenate([p[1] for p in parts]), whole_tr)
