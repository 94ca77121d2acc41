"""Generated prims live in their parent's space.

usdcrowd computes agents, cameras and events in the world of the stage it
reads, then authors each in the space of its parent prim: the world pose times
the inverse of the parent's local-to-world transform. A layer that moves,
rotates or scales an ancestor, or a set that references the shot under its own
(corrective, even animated) transform, then carries crowd, cameras and
scenery together, as every USD reader and DCC tool composes them. (A
``!resetXformStack!`` would pin them to the world instead; Blender ignores it,
so the two would disagree.)

Matrices are USD's: row vectors (``p' = p @ M``), in the stage's units.
"""

from __future__ import annotations

import numpy as np


class ParentSpace:
    """Parents' local-to-world transforms on a stage, over the time codes of a shot.

    Parameters
    ----------
    stage : Usd.Stage
        The stage whose world the poses are computed in.
    times : (t,) float
        Time codes at which a time-varying parent is sampled.
    """

    def __init__(self, stage, times):
        self.stage = stage
        self.times = np.asarray(times, dtype=np.float64)
        self._cache: dict[str, np.ndarray] = {}

    def of(self, path: str, times=None) -> np.ndarray:
        """Local-to-world of the parent of the prim at ``path``.

        The parent is the nearest ancestor that exists on the stage (the
        scopes a generated layer adds carry no transform).

        Parameters
        ----------
        times : (t,) float, optional
            Where a time-varying parent is sampled (default: the shot's time codes).

        Returns
        -------
        (4, 4) float64, or (t, 4, 4) when an ancestor's transform varies in time.
        """
        from pxr import Sdf

        parent = Sdf.Path(path).GetParentPath()
        while parent != Sdf.Path.absoluteRootPath and not self.stage.GetPrimAtPath(parent):
            parent = parent.GetParentPath()
        return self.world(str(parent), times)

    def world(self, path: str, times=None) -> np.ndarray:
        """Local-to-world of the prim at ``path`` (a prim that is not Xformable: its parent's).

        Returns
        -------
        (4, 4) float64, or (t, 4, 4) when its transform or an ancestor's varies in time.
        """
        from pxr import Usd, UsdGeom

        prim = self.stage.GetPrimAtPath(path)
        if not prim or prim.IsPseudoRoot():
            return np.eye(4)
        times = self.times if times is None else np.asarray(times, dtype=np.float64)
        if _varies(prim) and len(times) > 1:
            return np.array([np.array(UsdGeom.XformCache(Usd.TimeCode(float(t))).GetLocalToWorldTransform(prim))
                             for t in times], dtype=np.float64)
        key = str(path)
        if key not in self._cache:
            # A transform with one time sample holds it: read it at a time code, not at Default.
            t = Usd.TimeCode(float(times[0])) if len(times) else Usd.TimeCode.Default()
            self._cache[key] = np.array(UsdGeom.XformCache(t).GetLocalToWorldTransform(prim), dtype=np.float64)
        return self._cache[key]

    def table(self, paths) -> dict[str, np.ndarray]:
        """``{parent path: matrix}`` for the parents of ``paths``, identities left out (picklable)."""
        out = {}
        for p in paths:
            key = parent_key(p)
            if key not in out:
                out[key] = self.of(p)
        return {k: m for k, m in out.items() if not is_identity(m)}


def parent_key(path: str) -> str:
    """The key :meth:`ParentSpace.table` files ``path``'s parent under (its parent path)."""
    return str(path).rsplit("/", 1)[0] or "/"


def _varies(prim) -> bool:
    """Whether the transform of ``prim`` or of an ancestor may change in time."""
    from pxr import UsdGeom

    p = prim
    while p and not p.IsPseudoRoot():
        if p.IsA(UsdGeom.Xformable) and UsdGeom.Xformable(p).TransformMightBeTimeVarying():
            return True
        p = p.GetParent()
    return False


def is_identity(m: np.ndarray, tol: float = 1e-12) -> bool:
    """Whether ``m`` ((4, 4) or (t, 4, 4)) is the identity at every time."""
    return bool(np.abs(np.asarray(m) - np.eye(4)).max() <= tol)


def in_parent(world: np.ndarray, parent: np.ndarray | None) -> np.ndarray:
    """World transforms expressed in the parent's space: ``world @ inverse(parent)``.

    Parameters
    ----------
    world : (4, 4) or (t, 4, 4) float
    parent : (4, 4) or (t, 4, 4) float, or None (the identity)

    Returns
    -------
    (4, 4) or (t, 4, 4) float64, broadcast over time.
    """
    world = np.asarray(world, dtype=np.float64)
    if parent is None or is_identity(parent):
        return world
    return world @ np.linalg.inv(np.asarray(parent, dtype=np.float64))


def points_in_parent(points: np.ndarray, parent: np.ndarray | None) -> np.ndarray:
    """(t, 3) world points in the parent's space (``parent`` (4, 4) or (t, 4, 4), or None)."""
    if parent is None or is_identity(parent):
        return np.asarray(points, dtype=np.float64)
    return transform_points(points, np.linalg.inv(np.asarray(parent, dtype=np.float64)))


def transform_points(points: np.ndarray, m: np.ndarray) -> np.ndarray:
    """(..., 3) points times (4, 4) or (t, 4, 4) row-vector transforms (broadcast over time)."""
    points = np.asarray(points, dtype=np.float64)
    h = np.concatenate([points, np.ones(points.shape[:-1] + (1,))], axis=-1)
    return np.einsum("...i,...ij->...j", h, np.asarray(m, dtype=np.float64))[..., :3]


def scale_of(m: np.ndarray) -> np.ndarray:
    """Uniform scale of (4, 4) or (t, 4, 4) transforms (the first row's length): () or (t,) float."""
    return np.linalg.norm(np.asarray(m, dtype=np.float64)[..., 0, :3], axis=-1)
