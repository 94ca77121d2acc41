"""Steering forces on camera positions (seed 000, section 4.3).

Every force is Reynolds' "desired velocity minus current velocity"; the
caller weights and sums them (Algorithm 1). Arrays are over cameras (c,) or
over (camera, other) pairs from a spatial index; positions in metres,
velocities in m/s.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from . import framing


def arrival(position: np.ndarray, target: np.ndarray, velocity: np.ndarray, max_speed: np.ndarray,
            slow_distance: np.ndarray) -> np.ndarray:
    """Reynolds' arrival (Figure 3b): full speed toward ``target``, slowing inside ``slow_distance``.

    Parameters
    ----------
    position, target, velocity : (c, 3) float
    max_speed, slow_distance : (c,) float

    Returns
    -------
    (c, 3) float64
    """
    d = target - position
    dist = np.linalg.norm(d, axis=1)
    speed = max_speed * np.minimum(1.0, dist / np.maximum(slow_distance, 1e-9))
    desired = d / np.maximum(dist, 1e-9)[:, None] * speed[:, None]
    return desired - velocity


def framing_target(camera_xy: np.ndarray, a: np.ndarray, b: np.ndarray, alpha: np.ndarray, beta: np.ndarray,
                   min_width) -> np.ndarray:
    """(c, 2) nearest viewpoint that frames A and B under ``alpha`` (see :mod:`.framing`)."""
    poly = framing.viewpoint_range(a, b, camera_xy, alpha, beta, min_width)
    return framing.closest_on_polyline(poly, camera_xy)


def crane_height(n_members: np.ndarray, radius: np.ndarray, elevation: np.ndarray, crane_members: int,
                 crane_gain: float) -> np.ndarray:
    """(c,) desired camera height: eye level for a few people, a crane rising with a large group's radius."""
    lo, hi = elevation[:, 0], elevation[:, 1]
    eye = lo + 0.15 * (hi - lo)
    crane = lo + crane_gain * radius
    return np.clip(np.where(n_members >= crane_members, np.maximum(crane, eye), eye), lo, hi)


def obstacle_avoidance(position: np.ndarray, velocity: np.ndarray, forward: np.ndarray, right: np.ndarray,
                       target: np.ndarray, max_speed: np.ndarray, tan_x: np.ndarray, obstacle_tree: cKDTree | None,
                       obstacle_xyz: np.ndarray, obstacle_radius: np.ndarray, search: float,
                       clearance: float = 0.0) -> np.ndarray:
    """Algorithm 3: sidestep obstacles in the frustum that stand between the camera and its target.

    Parameters
    ----------
    position, velocity, forward, right, target : (c, 3) float
        ``target`` is k, the centre of the event's characters (for a scouting
        camera, which has no event, the character it looks at: scouts also
        keep their view clear).
    tan_x : (c,) float
        Half horizontal field-of-view tangent.
    obstacle_tree : cKDTree or None
        Over the obstacles' centres seen from above.
    obstacle_xyz : (o, 3) float
        Obstacle centres (half their height up).
    obstacle_radius : (o,) float
        Horizontal radius of each footprint.
    search : float
        Metres around each camera searched.
    clearance : float
        A camera higher than an obstacle's top by this flies over it: no sidestep for it.

    Returns
    -------
    force : (c, 3) float64
        F_obs, horizontal.
    clear_height : (c,) float64
        Height of the tallest obstacle in the way (0 where none): where the
        camera may rise above it, the crane does (see CameraAgents.step).
    """
    out = np.zeros_like(position)
    clear = np.zeros(len(position))
    if obstacle_tree is None or len(position) == 0:
        return out, clear
    lists = obstacle_tree.query_ball_point(position[:, :2], r=search)
    ci = np.repeat(np.arange(len(position)), [len(x) for x in lists])
    if len(ci) == 0:
        return out, clear
    oi = np.concatenate([np.asarray(x, dtype=np.int64) for x in lists])
    d = obstacle_xyz[oi] - position[ci]
    z = np.einsum("ij,ij->i", d, forward[ci])
    x = np.einsum("ij,ij->i", d, right[ci])
    # In the frustum (seen from above, widened by the obstacle's radius) ...
    in_view = (z > 0) & (np.abs(x) <= tan_x[ci] * z + obstacle_radius[oi])
    # ... and closer to the camera than the target is, along the view. The paper
    # prints (p - k) . l on the right, which is negative whenever the target is in
    # front and would never fire; (k - p) . l is what its text describes.
    closer = z < np.einsum("ij,ij->i", target[ci] - position[ci], forward[ci])
    hit = in_view & closer
    np.maximum.at(clear, ci[hit], 2.0 * obstacle_xyz[oi[hit], 2])
    # A camera already above an obstacle flies over it (the crane holds it there): sidestepping would
    # hold it back on the near side, behind it.
    hit &= position[ci, 2] <= 2.0 * obstacle_xyz[oi, 2] + clearance
    side = np.where(x[hit] > 0, -1.0, 1.0)                 # on the right: go left
    u = side[:, None] * right[ci[hit]] * max_speed[ci[hit], None]
    f = u - velocity[ci[hit]]
    f[:, 2] = 0.0
    np.add.at(out, ci[hit], f)
    return out, clear


def separation(position: np.ndarray, velocity: np.ndarray, forward: np.ndarray, right: np.ndarray,
               max_speed: np.ndarray, distance: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """Algorithm 4: push apart cameras that are close and look the same way.

    Parameters
    ----------
    pairs : (p, 2) int
        Camera pairs closer than the largest separation distance (from a
        KD-tree); each is used in both directions.

    Returns
    -------
    (c, 3) float64
        F_sep.
    """
    out = np.zeros_like(position)
    if len(pairs) == 0:
        return out
    c = np.concatenate([pairs[:, 0], pairs[:, 1]])
    i = np.concatenate([pairs[:, 1], pairs[:, 0]])
    d = position[i] - position[c]
    near = np.linalg.norm(d, axis=1) < distance[c]
    c, i, d = c[near], i[near], d[near]
    side = np.where(np.einsum("ij,ij->i", d, right[c]) > 0, -1.0, 1.0)     # the other on my right: go left
    u = side[:, None] * right[c] * max_speed[c, None]
    same_way = np.maximum(0.0, np.einsum("ij,ij->i", forward[c], forward[i]))
    np.add.at(out, c, same_way[:, None] * (u - velocity[c]))
    return out


def wandering(velocity: np.ndarray, heading: np.ndarray, max_speed: np.ndarray, share: float) -> np.ndarray:
    """Reynolds' wander: a desired velocity along a slowly drifting horizontal heading, (c, 3)."""
    desired = np.stack([np.cos(heading), np.sin(heading), np.zeros_like(heading)], 1) * (share * max_speed)[:, None]
    f = desired - velocity
    f[:, 2] = 0.0
    return f


def containment(position: np.ndarray, velocity: np.ndarray, centre: np.ndarray, radius: float,
                max_speed: np.ndarray) -> np.ndarray:
    """Pull cameras that wandered beyond ``radius`` of the crowd's centre back toward it, (c, 3)."""
    d = centre[None, :2] - position[:, :2]
    dist = np.linalg.norm(d, axis=1)
    out = np.zeros_like(position)
    far = dist > radius
    out[far, :2] = d[far] / dist[far, None] * max_speed[far, None] - velocity[far, :2]
    return out


def elevation(position: np.ndarray, velocity: np.ndarray, height: np.ndarray, max_speed: np.ndarray,
              slow_distance: float = 2.0) -> np.ndarray:
    """Vertical arrival toward ``height`` (c,): the crane's move, (c, 3)."""
    dz = height - position[:, 2]
    vz = np.clip(dz / slow_distance, -1.0, 1.0) * max_speed
    out = np.zeros_like(position)
    out[:, 2] = vz - velocity[:, 2]
    return out
