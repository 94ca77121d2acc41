"""Where cameras start or stand: rings around the crowd, static cameras, generated agents."""

from __future__ import annotations

import numpy as np

from ..core import model
from ..core.view import look_at

# A 35 mm lens on a full-frame 16:9 crop (the lens of generated cameras).
FOCAL_LENGTH = 35.0
H_APERTURE = 36.0
V_APERTURE = 20.25
# CameraAgentAPI's fallbacks (schemas/schema.usda), for generated camera agents.
AGENT_DEFAULTS = {"max_speed": 3.0, "max_force": 2.0, "max_angular_speed": np.radians(60.0),
                  "arrival_distance": 4.0, "aim_threshold": np.radians(15.0), "separation_distance": 5.0,
                  "view_angle": 0.6, "elevation": (1.5, 8.0)}


def crowd_extent(positions: np.ndarray, quantile: float = 0.9) -> tuple[np.ndarray, float]:
    """Centre (3,) and radius of a crowd's positions ``(..., 3)`` (the ``quantile`` of distances)."""
    p = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    p = p[np.isfinite(p).all(axis=1)]
    if len(p) == 0:
        return np.zeros(3), 1.0
    centre = np.median(p, axis=0)
    radius = float(np.quantile(np.linalg.norm(p[:, :2] - centre[:2], axis=1), quantile))
    return centre, max(radius, 1.0)


def ring(centre: np.ndarray, radius: float, height: float, count: int, phase: float = 0.0,
         look_height: float = 1.0) -> np.ndarray:
    """(count, 4, 4) cameras evenly on a ring around ``centre``, looking at it."""
    ang = phase + 2 * np.pi * np.arange(count) / max(count, 1)
    eye = np.column_stack([centre[0] + radius * np.cos(ang), centre[1] + radius * np.sin(ang),
                           np.full(count, height)])
    target = np.tile([centre[0], centre[1], look_height], (count, 1))
    return look_at(eye, target)


def static_cameras(positions: np.ndarray, count: int, times: np.ndarray, root: str = "/World",
                   height: float = 7.0, bounds: np.ndarray | None = None, seed: int = 0) -> list[model.CameraTrack]:
    """Static cameras at strategic positions: each frames one of the places the crowd uses most.

    The baseline of seed 000's evaluation, placed knowing where the crowd
    goes over the whole shot (knowledge the autonomous cameras do not have):
    the crowd's positions over the shot are split into ``count`` clusters
    (k-means), and each camera stands outward of its cluster (away from the
    crowd's centre) at the distance where the cluster's extent fills 90 % of
    its horizontal field of view, ``height`` metres up, looking at the
    cluster's centre.

    Parameters
    ----------
    positions : (t, n, 3) float
        The crowd over the shot (any subsample of frames).
    count : int
    times : (t,) float
        Time codes of the shot.
    bounds : (2, 2) float, optional
        Walkable area the cameras stand in (indoors they stay inside).
    seed : int
        Seeds k-means.
    """
    from scipy.cluster.vq import kmeans2

    p = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    p = p[np.isfinite(p).all(axis=1)][:, :2]
    if len(p) == 0 or count == 0:
        return []
    centre = np.median(p, axis=0)
    k = min(count, len(np.unique(p, axis=0)))
    means, label = kmeans2(p, k, seed=np.random.default_rng(seed), minit="++")
    half_fov = np.arctan(0.5 * H_APERTURE / FOCAL_LENGTH)
    out = []
    for j in range(count):
        c = means[j % k]
        mine = p[label == j % k]
        r = max(3.0, float(np.quantile(np.linalg.norm(mine - c, axis=1), 0.9))) if len(mine) else 3.0
        away = c - centre
        turn = 2 * np.pi * j / count
        if np.linalg.norm(away) < 1.0 or j >= k:          # a central cluster (or a repeat): any side
            away = np.array([np.cos(turn), np.sin(turn)])
        away /= np.linalg.norm(away)
        eye = np.append(c + away * r / np.tan(0.9 * half_fov), height)
        if bounds is not None:
            b = np.asarray(bounds, dtype=np.float64)
            eye[:2] = np.clip(eye[:2], b[0] + 1.0, np.maximum(b[0] + 1.0, b[1] - 1.0))
        m = look_at(eye, np.append(c, 1.0))[0]
        out.append(model.CameraTrack(f"{root}/Cameras/Static{j + 1:02d}", np.asarray(times, dtype=np.float64),
                                     np.repeat(m[None], len(times), axis=0), np.full(len(times), FOCAL_LENGTH),
                                     H_APERTURE, V_APERTURE, 0.1, 1000.0))
    return out


def generated_agents(count: int, centre: np.ndarray, radius: float, root: str = "/World",
                     start: int = 1, bounds: np.ndarray | None = None) -> model.CameraAgentTable:
    """``count`` camera agents with the schema's default limits, on a ring around the crowd.

    With ``bounds`` ((2, 2) walkable area), the ring is pulled in to start inside it.
    """
    d = AGENT_DEFAULTS
    lo, hi = d["elevation"]
    mats = ring(centre, radius + 5.0, 0.5 * (lo + hi), count)
    if bounds is not None:
        b = np.asarray(bounds, dtype=np.float64)
        eye = mats[:, 3, :3].copy()
        eye[:, :2] = np.clip(eye[:, :2], b[0] + 1.0, np.maximum(b[0] + 1.0, b[1] - 1.0))
        mats = look_at(eye, np.tile([centre[0], centre[1], 1.0], (count, 1)))
    full = lambda v: np.full(count, float(v))
    return model.CameraAgentTable(
        [f"{root}/Cameras/Agent{k + start:02d}" for k in range(count)], mats, full(FOCAL_LENGTH),
        full(H_APERTURE), full(V_APERTURE), full(0.1), full(1000.0),
        np.full(count, model.code(model.CAMERA_MODES, "scouting"), np.int8), full(d["max_speed"]),
        full(d["max_force"]), full(d["max_angular_speed"]), full(d["arrival_distance"]),
        full(d["aim_threshold"]), full(d["separation_distance"]), full(d["view_angle"]),
        np.tile([lo, hi], (count, 1)).astype(np.float64), [None] * count)


def concat_agents(a: model.CameraAgentTable, b: model.CameraAgentTable) -> model.CameraAgentTable:
    """Rows of ``a`` then ``b``."""
    out = {}
    for k, v in vars(a).items():
        w = getattr(b, k)
        out[k] = v + w if isinstance(v, list) else np.concatenate([v, w])
    return model.CameraAgentTable(**out)


def take_agents(a: model.CameraAgentTable, rows) -> model.CameraAgentTable:
    """The given rows of a camera agent table."""
    rows = np.asarray(rows, dtype=np.int64)
    return model.CameraAgentTable(**{k: ([v[i] for i in rows] if isinstance(v, list) else v[rows])
                                     for k, v in vars(a).items()})
