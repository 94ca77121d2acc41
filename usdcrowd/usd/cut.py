"""The edited cut as a camera: CutCam in cameras.usda (CutCameraAPI).

CutCam takes, at each frame, the pose and lens of the camera on air. At a
cut it jumps: one more sample, a thousandth of a frame before the cut frame,
holds the outgoing camera's pose there, so that a renderer sampling between
frames (motion blur) never sees a pose between two cameras.
"""

from __future__ import annotations

import os

import numpy as np

from .. import schema
from ..core import model

CUT_CAMERA = "CutCam"
# Time codes before a cut frame where the outgoing camera's pose is held.
CUT_EPSILON = 1e-3


def cut_track(path: str, tracks: list[model.CameraTrack], on_air: np.ndarray) -> model.CameraTrack:
    """The track of a camera playing ``tracks[on_air[i]]`` at frame ``i``.

    Parameters
    ----------
    path : str
        The cut camera's prim path.
    tracks : list[CameraTrack]
        Sampled at the same frames.
    on_air : (t,) int
        Index into ``tracks`` per frame.

    Notes
    -----
    The cut camera keeps the first track's apertures; each camera's lens is
    rescaled to them so that the horizontal field of view is the one on air.
    """
    times = np.asarray(tracks[0].times, dtype=np.float64)
    on_air = np.asarray(on_air, dtype=np.int64)
    h_ap, v_ap = tracks[0].horizontal_aperture, tracks[0].vertical_aperture
    poses = np.stack([tr.cam_to_world for tr in tracks])                 # (c, t, 4, 4)
    focal = np.stack([tr.focal_length * h_ap / tr.horizontal_aperture for tr in tracks])
    frames = np.arange(len(times))
    cuts = np.flatnonzero(np.diff(on_air)) + 1
    # Before each cut frame: the outgoing camera at the cut frame (where it would have been).
    t_all = np.concatenate([times, times[cuts] - CUT_EPSILON])
    cam_all = np.concatenate([on_air, on_air[cuts - 1]])
    f_all = np.concatenate([frames, cuts])
    order = np.argsort(t_all, kind="stable")
    t_all, cam_all, f_all = t_all[order], cam_all[order], f_all[order]
    near = min(tr.near for tr in tracks)
    far = max(tr.far for tr in tracks)
    return model.CameraTrack(path, t_all, poses[cam_all, f_all], focal[cam_all, f_all], h_ap, v_ap, near, far)


def write_cut_camera(cameras_path: str | os.PathLike, track: model.CameraTrack, record: dict, parents=None) -> str:
    """Add (or replace) the cut camera in a shot's cameras layer, atomically.

    Parameters
    ----------
    track : CameraTrack
        From :func:`cut_track`.
    record : dict
        Per frame (at the shot's frames): ``times`` (t,), ``camera`` (t,) prim
        paths, ``event`` (t,) prim paths or "", ``shot`` (t,) int from 1 and
        ``reason`` (t,) str; authored where they change.
    """
    from pxr import Sdf

    from .cameras import _changes, add_camera

    def author(layer, spec):
        api = list(spec.GetInfo("apiSchemas").GetAddedOrExplicitItems()) if spec.HasInfo("apiSchemas") else []
        spec.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=api + [schema.CUT_CAMERA_API]))
        times = [float(t) for t in record["times"]]
        for name, type_name, values in (("crowd:cut:camera", Sdf.ValueTypeNames.String, record["camera"]),
                                        ("crowd:cut:event", Sdf.ValueTypeNames.String, record["event"]),
                                        ("crowd:cut:shot", Sdf.ValueTypeNames.Int, [int(v) for v in record["shot"]]),
                                        ("crowd:cut:reason", Sdf.ValueTypeNames.String, record["reason"])):
            attr = Sdf.AttributeSpec(spec, name, type_name)
            values = list(values)
            for i in _changes(values):
                layer.SetTimeSample(attr.path, times[i], values[i])

    return add_camera(cameras_path, track, None, parents=parents, author=author)
