"""``usdcrowd edit``: a director cuts a shot's cameras into one film.

The shot's crowd, events and scenery come back as for ``usdcrowd cameras``
(:func:`usdcrowd.jobs.filming.load_shot`); its cameras are read from the
composed stage as every renderer sees them. The director
(:mod:`usdcrowd.editing`) plans the cut; it is written as

- ``CutCam`` in the shot's cameras.usda (CutCameraAPI): any USD tool and
  both renderers play the edit, and the renderers' per-frame ground truth
  says which camera is on air and why;
- ``cut.otio`` in the output folder (OpenTimelineIO: one clip per shot);
- ``onair.csv``: per frame, the camera on air, its event and the numbers
  behind the choice;
- ``cut.mp4`` and ``cut_sheet.png`` (one tile per shot): the cut through
  the OpenGL preview (the ``preview`` extra; ``--no-video`` skips them).
"""

from __future__ import annotations

import csv
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core import model
from ..core.errors import StageError
from ..editing import Cut, EditParams, plan_cut
from ..editing.coverage import Coverage, coverage


@dataclass
class EditResult:
    """What ``usdcrowd edit`` made."""

    cut: Cut
    coverage: Coverage
    cameras: list                  # candidate camera prim paths (Cut.camera indexes them)
    events: list                   # event prim paths (Cut.event indexes them)
    times: np.ndarray
    fps: float
    reasons: list                  # per shot
    paths: dict = field(default_factory=dict)


def camera_tracks(scene, paths: list[str], times: np.ndarray) -> list[model.CameraTrack]:
    """Cameras of a :class:`~usdcrowd.scenario.shot_scene.ShotScene` sampled at ``times``, canonical metres."""
    out = []
    for path in paths:
        views = [scene.camera(path, float(t)) for t in times]
        out.append(model.CameraTrack(path, np.asarray(times, dtype=np.float64),
                                     np.stack([v.cam_to_world for v in views]),
                                     np.array([v.focal_length for v in views]), views[0].horizontal_aperture,
                                     views[0].vertical_aperture, views[0].near, views[0].far))
    return out


def candidate_cameras(scene, asked: list[str] | None) -> list[str]:
    """The cameras the director may cut between: ``asked``, or every camera but cut cameras.

    Raises
    ------
    StageError
        A name that is not a camera of the shot.
    """
    from .. import schema

    def is_cut(path):
        return scene.stage.GetPrimAtPath(path).HasAPI(schema.CUT_CAMERA_API)

    every = [p for p in scene.camera_paths if not is_cut(p)]
    if not asked:
        if not every:
            raise StageError("the shot has no camera to cut between", file=scene.path)
        return every
    by_name = {}
    for p in every:
        by_name.setdefault(p.rsplit("/", 1)[-1], []).append(p)
    out = []
    for name in asked:
        found = [name] if name in every else by_name.get(name, [])
        if len(found) != 1:
            known = ", ".join(p.rsplit("/", 1)[-1] for p in every)
            what = "names more than one camera" if found else "is not a camera of the shot"
            raise StageError(f"{what} (cameras: {known})", file=scene.path, prim=name, attribute="--cameras")
        if found[0] not in out:
            out.append(found[0])
    return out


def shot_reason(cut: Cut, cov: Coverage, k: int, events: model.EventTable, params: EditParams, fps: float) -> str:
    """Why shot ``k`` of ``cut`` is on air, in words (its means over the shot)."""
    shot = cut.shots[k]
    span = slice(shot.start, shot.end)
    if shot.event < 0:
        shown = float(np.mean(cov.shown[shot.camera, span]))
        text = f"no event framed: {shown:.1f} people shown legibly"
    else:
        e = events[shot.event]
        kind = model.EVENT_KINDS[e.kind]
        imp = float(np.mean(cut.importance[shot.event, span]))
        share = float(np.mean(cov.share[shot.camera, shot.event, span]))
        size = float(np.mean(cov.size[shot.camera, shot.event, span]))
        text = (f"{e.path.rsplit('/', 1)[-1]} ({kind}, importance {imp:.2f}): {share:.0%} of its people visible, "
                f"{size:.0%} of the frame's height")
    if shot.held_long:
        text += f"; held {shot.frames / fps:.1f} s, no allowed cut to another camera"
    return text


def edit_shot(shot_path: str | os.PathLike, out_dir: str | os.PathLike, cameras: list[str] | None = None,
              params: EditParams | None = None, video: bool = True, resolution=(640, 360),
              progress: bool = True, limits=None) -> EditResult:
    """Cut a shot's cameras into one film (see the module).

    Parameters
    ----------
    shot_path : path-like
        The shot (or a stage over it).
    out_dir : path-like
        Folder for cut.otio, onair.csv and the preview (created).
    cameras : list of str, optional
        Camera prim paths or names to cut between (default: all but cut cameras).
    params : EditParams, optional
    video : bool
        Render cut.mp4 and cut_sheet.png with the OpenGL preview.
    """
    from ..atomic import output_dir
    from ..exchange.timeline import _otio, write_timeline
    from ..scenario.shot_scene import ShotScene
    from ..usd.cameras import CAMERAS
    from ..usd.cut import CUT_CAMERA, cut_track, write_cut_camera
    from .filming import load_shot
    from .pipeline import frame_progress

    params = params or EditParams()
    _otio()                                     # before any work: the timeline is the cut's main output
    if video:
        _preview_available()
    out = output_dir(out_dir, "edit")
    sc = load_shot(shot_path, progress=progress, limits=limits)
    scene = ShotScene(sc.shot)
    paths = candidate_cameras(scene, cameras)
    times = np.asarray(sc.scenario.time.codes, dtype=np.float64)
    fps = float(sc.scenario.time.fps)
    tracks = camera_tracks(scene, paths, times)
    visible = np.asarray(sc.scenario.agents.visible, bool)
    with frame_progress(len(times), "coverage", progress) as bar:
        cov = coverage(tracks, sc.positions, sc.events, visible, sc.scenario.obstacles, params, fps,
                       progress=bar.update, overhead=sc.scenario.overhead, heights=sc.scenario.agents.height)
    cut = plan_cut(cov, sc.events, fps, params, visible)
    reasons = [shot_reason(cut, cov, k, sc.events, params, fps) for k in range(len(cut.shots))]
    result = EditResult(cut, cov, paths, [e.path for e in sc.events], times, fps, reasons)

    # The record per frame: the shot's camera, event and reason (what CutCam carries), and the numbers.
    shot_of = np.zeros(len(times), np.int64)
    for k, s in enumerate(cut.shots):
        shot_of[s.start:s.end] = k
    ev_path = [sc.events[s.event].path if s.event >= 0 else "" for s in cut.shots]
    record = {"times": times, "camera": [paths[c] for c in cut.camera], "event": [ev_path[k] for k in shot_of],
              "shot": shot_of + 1, "reason": [reasons[k] for k in shot_of]}
    root = scene.stage.GetDefaultPrim()
    cut_path = f"{root.GetPath() if root else ''}/Cameras/{CUT_CAMERA}"
    from ..scenario.parent_space import ParentSpace

    track = cut_track(cut_path, tracks, cut.camera)
    result.paths["cameras"] = write_cut_camera(Path(sc.shot).parent / CAMERAS, track, record,
                                               parents=ParentSpace(scene.stage, track.times))
    result.paths["cut_camera"] = cut_path

    result.paths["csv"] = _write_onair(out / "onair.csv", result, shot_of, ev_path, reasons)
    shots = [{"camera": paths[s.camera], "start": float(times[s.start]), "frames": s.frames, "event": ev_path[k],
              "reason": reasons[k]} for k, s in enumerate(cut.shots)]
    # The shot itself (not a stage placing it in a set): the camera paths in the timeline are its own.
    media = os.path.relpath(os.path.abspath(sc.shot), os.path.abspath(out))
    result.paths["otio"] = write_timeline(out / "cut.otio", Path(sc.shot).parent.name or "shot", media, fps,
                                          float(times[0]), float(times[-1]), shots)
    if video:
        result.paths.update(_preview(sc.shot, out, cut_path, times, cut, paths, ev_path, resolution, progress))
    return result


def _write_onair(path: Path, r: EditResult, shot_of: np.ndarray, ev_path: list[str], reasons: list[str]) -> str:
    from ..atomic import atomic_path

    cut, cov = r.cut, r.coverage
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["time_code", "shot", "camera", "event", "frame_event", "importance", "visible_share",
                    "screen_height", "value", "reason"])
        for i, t in enumerate(r.times):
            c, k = int(cut.camera[i]), int(shot_of[i])
            e = cut.shots[k].event
            fe = int(cut.best_event[c, i])
            w.writerow([f"{t:g}", k + 1, r.cameras[c], ev_path[k], r.events[fe] if fe >= 0 else "",
                        f"{cut.importance[e, i]:.4f}" if e >= 0 else "0",
                        f"{cov.share[c, e, i]:.4f}" if e >= 0 else "0",
                        f"{cov.size[c, e, i]:.4f}" if e >= 0 else "0", f"{cut.value[c, i]:.4f}", reasons[k]])
    return os.fspath(path)


def _preview_available() -> None:
    """The preview's own check (:func:`~usdcrowd.render.preview.context.require_moderngl`), naming --no-video."""
    from ..core.errors import UsdcrowdError
    from ..render.preview.context import require_moderngl

    try:
        require_moderngl()
    except UsdcrowdError as exc:
        raise UsdcrowdError(f"the cut's preview (cut.mp4): {exc}, or leave it out with --no-video") from None


def _preview(shot_path, out: Path, cut_path: str, times, cut: Cut, paths, ev_path, resolution, progress) -> dict:
    """cut.mp4 through CutCam, and cut_sheet.png: one tile per shot (its middle frame)."""
    from ..render.preview.output import contact_sheet, write_png, write_sequence
    from ..render.preview.renderer import PreviewRenderer

    r = PreviewRenderer(shot_path, *resolution)
    try:
        written = write_sequence(r, times, cut_path, video=out / "cut.mp4", progress=progress)
        thumbs, labels = [], []
        for k, s in enumerate(cut.shots):
            mid = float(times[(s.start + s.end - 1) // 2])
            thumbs.append(r.render(mid, cut_path).color)
            event = ev_path[k].rsplit("/", 1)[-1] if ev_path[k] else "no event"
            labels.append(f"{k + 1} {paths[s.camera].rsplit('/', 1)[-1]} {times[s.start]:g}-{times[s.end - 1]:g} "
                          f"{event}")
    finally:
        r.release()
    sheet = write_png(contact_sheet(thumbs, labels, columns=min(4, len(thumbs)), thumb_width=resolution[0] // 2),
                      out / "cut_sheet.png")
    return {"mp4": written["mp4"], "sheet": sheet}
