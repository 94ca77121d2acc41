"""Frustum culling and level-of-detail choice per character (seed 004).

Each agent is bounded by a sphere around its waist joint. Agents whose
sphere misses the view frustum are not drawn; the others get a level from
their height on screen in pixels: the full mesh (or clustered meshes, when
configured), impostors (:mod:`.impostors`), or, for the smallest, a
number of points from the body's octree-ordered list that shrinks with the
size (seed 004: "the number of points to be rendered is obtained as a
function of the distance for each character").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...character import rig

# Sphere radius around the waist joint, in body heights: covers the head top
# (0.4 of a height above the waist) and the feet (0.6 below) in any pose.
BOUND_RADIUS = 0.66 * rig.HEAD_TOP

LEVEL_FULL = 0    # then the clustered meshes, then the point levels, largest first


@dataclass(frozen=True)
class LodSettings:
    """Thresholds of the level of detail.

    Attributes
    ----------
    enabled : bool
        False: every visible character gets the full mesh (exact silhouettes
        for ground truth), culling still applies.
    cull : bool
        Frustum culling.
    shadow_bias : int
        Shadow casters are drawn this many mesh levels coarser than in the
        view (never coarser than the last mesh; impostors and points keep
        their level): a shadow on the floor needs less detail than the
        figure casting it.
    shadow_cell : float
        Mesh-level characters cast their shadows with the body clustered on
        this grid, metres, when it is coarser than their own level's (a
        third of the full mesh's triangles at 0.06 m; 0: no shadow mesh).
    mesh_levels : tuple of (min_px, cell)
        Mesh levels from the finest: characters at least ``min_px`` tall on
        screen get the mesh clustered on a ``cell``-metre grid (0: the full
        mesh, which must come first).
    impostor_min_px : float or None
        Characters smaller than the last mesh level and at least this tall
        are drawn as impostors (:mod:`.impostors`); None: no
        impostor level.
    max_meshes : int or None
        At most this many drawn characters get a mesh level, the tallest on
        screen; the others drop to the impostor level. A dense crowd seen
        from close by would otherwise be millions of triangles (3,000 full
        meshes in the volcano's Village view: 1.7 fps on llvmpipe; past a
        few dozen, each mesh costs more than the impostors of a hundred
        characters). None: no limit; ignored without an impostor level.
    point_levels : tuple of (min_px, n_points, splat_m)
        Point levels from the largest: characters at least ``min_px`` tall
        draw the first ``n_points`` points of the octree list, each a square
        splat ``splat_m`` metres wide (sized so the splats close the
        silhouette at that many points).
    """

    enabled: bool = True
    cull: bool = True
    shadow_bias: int = 1
    shadow_cell: float = 0.06
    # Below 100 px an impostor's texels are no coarser than pixels (impostors.CELL).
    mesh_levels: tuple = ((100.0, 0.0),)
    # Impostors cost a software rasteriser less than 48 points down to a few
    # pixels (bench_preview), so points are kept for specks.
    impostor_min_px: float | None = 3.0
    point_levels: tuple = ((1.5, 16, 0.45), (0.0, 8, 0.6))
    max_meshes: int | None = 32

    @property
    def n_meshes(self) -> int:
        return len(self.mesh_levels)

    @property
    def impostor_level(self) -> int | None:
        """Index of the impostor level, or None."""
        return None if self.impostor_min_px is None else self.n_meshes

    @property
    def first_point_level(self) -> int:
        return self.n_meshes + (self.impostor_min_px is not None)

    @property
    def n_levels(self) -> int:
        return self.first_point_level + len(self.point_levels)

    @property
    def cells(self) -> tuple:
        """Clustering grids of the coarser mesh levels."""
        return tuple(cell for _, cell in self.mesh_levels[1:])

    def thresholds(self) -> np.ndarray:
        """Smallest on-screen height (pixels) of every level, largest first."""
        imp = [] if self.impostor_min_px is None else [self.impostor_min_px]
        return np.array([m[0] for m in self.mesh_levels] + imp + [p[0] for p in self.point_levels], dtype=np.float64)


def agent_bounds(joints_world: np.ndarray):
    """Bounding spheres of agents.

    Parameters
    ----------
    joints_world : (n, 3, 4, 4) float
        AgentPoses.joints_world.

    Returns
    -------
    centres : (n, 3) float64
        World position of the waist joint.
    radius : (n,) float64
        Metres (body height times the agent's scale).
    height : (n,) float64
        Body height in metres.
    """
    j = np.asarray(joints_world, dtype=np.float64)
    scale = np.linalg.norm(j[:, 0, 0, :3], axis=-1)
    return j[:, 1, 3, :3].copy(), BOUND_RADIUS * scale, rig.HEAD_TOP * scale


def in_frustum(centres: np.ndarray, radius: np.ndarray, world_to_cam: np.ndarray, focal_px: float,
               width: int, height: int, near: float, far: float) -> np.ndarray:
    """Spheres that touch a pinhole camera's view frustum.

    Parameters
    ----------
    centres : (n, 3) float
        World positions.
    radius : (n,) float
    world_to_cam : (4, 4) float
        Row-vector view matrix; the camera looks down -Z.
    focal_px : float
        Focal length in pixels (CameraView.intrinsics()[0, 0]).
    width, height : int
    near, far : float

    Returns
    -------
    (n,) bool
    """
    c = centres @ world_to_cam[:3, :3] + world_to_cam[3, :3]
    x, y, z = c[:, 0], c[:, 1], -c[:, 2]
    ok = (z > near - radius) & (z < far + radius)
    for half, coord in ((width / 2.0, x), (height / 2.0, y)):
        # Side planes through the eye: f * |coord| - half * z <= r * |normal|.
        norm = np.hypot(focal_px, half)
        ok &= focal_px * np.abs(coord) - half * z <= radius * norm
    return ok


def screen_height(centres: np.ndarray, body_height: np.ndarray, world_to_cam: np.ndarray,
                  focal_px: float) -> np.ndarray:
    """Height of each character on screen, pixels (inf when at or behind the eye)."""
    z = -(centres @ world_to_cam[:3, 2] + world_to_cam[3, 2])
    with np.errstate(divide="ignore"):
        return np.where(z > 1e-6, body_height * focal_px / z, np.inf)


def choose_levels(pixels: np.ndarray, settings: LodSettings, drawn: np.ndarray | None = None) -> np.ndarray:
    """Level of each character from its height on screen.

    Parameters
    ----------
    pixels : (n,) float
        :func:`screen_height`.
    drawn : (n,) bool, optional
        The characters that will be drawn: ``settings.max_meshes`` counts
        only them. Default: all.

    Returns
    -------
    (n,) int8
        LEVEL_FULL, then the clustered meshes, the impostor level (if any),
        then ``first_point_level + k`` for point level k.
    """
    if not settings.enabled:
        return np.zeros(len(pixels), dtype=np.int8)
    # Thresholds from the largest down; a character takes the first it reaches.
    thresholds = settings.thresholds()
    pixels = np.asarray(pixels, dtype=np.float64)
    level = np.minimum(np.searchsorted(-thresholds, -pixels, side="left"), settings.n_levels - 1)
    budget, imp = settings.max_meshes, settings.impostor_level
    if budget is not None and imp is not None:
        meshed = np.flatnonzero((level < imp) & (True if drawn is None else np.asarray(drawn, dtype=bool)))
        if len(meshed) > budget:
            # Keep the tallest; argpartition is linear where a sort is not.
            smaller = meshed[np.argpartition(-pixels[meshed], budget)[budget:]]
            level[smaller] = imp
    return level.astype(np.int8)


def shadow_levels(levels: np.ndarray, settings: LodSettings) -> np.ndarray:
    """Levels of the shadow casters: ``settings.shadow_bias`` mesh levels coarser."""
    last_mesh = settings.n_meshes - 1
    coarser = np.minimum(levels + settings.shadow_bias, last_mesh)
    return np.where(levels <= last_mesh, coarser, levels).astype(np.int8)


def group_by_level(levels: np.ndarray, visible: np.ndarray, n_levels: int, distance: np.ndarray | None = None):
    """Order of agents so each level's instances are contiguous.

    Parameters
    ----------
    levels : (n,) int
    visible : (n,) bool
        Agents to draw.
    n_levels : int
    distance : (n,) float, optional
        Within a level, draw nearest first: in a dense crowd the early depth
        test then rejects most hidden fragments before they are shaded.

    Returns
    -------
    order : (m,) int64
        Indices of the drawn agents, grouped by level.
    starts : (n_levels + 1,) int64
        Level k's instances are ``order[starts[k]:starts[k + 1]]``.
    """
    drawn = np.flatnonzero(visible)
    if distance is not None:
        drawn = drawn[np.argsort(distance[drawn], kind="stable")]
    order = drawn[np.argsort(levels[drawn], kind="stable")]
    counts = np.bincount(levels[drawn], minlength=n_levels)[:n_levels]
    return order, np.concatenate([[0], np.cumsum(counts)])
