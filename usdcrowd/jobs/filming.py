"""Re-filming and evaluating an existing shot, without re-simulating the crowd.

``usdcrowd cameras`` and ``usdcrowd metrics`` run here: the crowd comes back
from the shot's crowd layer (:func:`usdcrowd.scenario.crowd.read_crowd`),
the events from its CrowdEvent prims (detected again only if the crowd
layer has none), the scenery and the authored camera agents from the
scenario the shot refers to.
"""

from __future__ import annotations

import csv
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core import model
from ..core.errors import StageError, UsdcrowdError
from ..core.framestore import FrameStore

# Cameras one command may film (of each kind for metrics): each is a (frames, 4, 4) track and a
# steering agent, so a typing mistake (a million) would allocate without bound.
MAX_CAMERAS = 1000


def check_camera_count(n: int, option: str) -> None:
    """Refuse more than :data:`MAX_CAMERAS` cameras, naming the option that asked for them."""
    if n > MAX_CAMERAS:
        raise UsdcrowdError(f"{option}: {n:,} cameras is too many (at most {MAX_CAMERAS:,} cameras)")


@dataclass
class ShotCrowd:
    """An existing shot read back for the cameras."""

    shot: str
    out_dir: Path
    scenario: model.Scenario
    positions: FrameStore          # (t, n, 3) float32, scenario rows, on disk
    events: model.EventTable
    detected_now: bool             # events were missing from the crowd layer and were detected here
    default_prim: str
    frame: object                  # StageFrame
    parents: object = None         # ParentSpace of the shot stage: cameras and events are authored in it


def load_shot(shot_path: str | os.PathLike, seed: int | None = None, progress: bool = True,
              limits=None) -> ShotCrowd:
    """Read a shot's crowd, events, scenery and camera agents.

    Raises
    ------
    StageError
        If the shot names no scenario, or its crowd layer holds no agents.
    """
    from ..events import EventDetector
    from ..events.scenario import layer_events
    from ..scenario import load_scenario, open_stage, stage_frame
    from .pipeline import frame_progress
    from ..scenario.events import layer_generator, read_events
    from ..scenario.parent_space import ParentSpace
    from ..scenario.stageio import time_range

    from ..usd.shot import find_shot

    shot_path = find_shot(shot_path)       # a stage over the shot or a set placing it: the shot itself
    stage = open_stage(shot_path)
    data = dict(stage.GetRootLayer().customLayerData.get("usdcrowd", {}))
    ref = data.get("scenario")
    if not ref:
        raise StageError("not a usdcrowd shot: customLayerData has no usdcrowd.scenario", file=shot_path)
    scenario_path = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(shot_path)), ref))
    scenario = load_scenario(scenario_path, seed=seed if seed is not None else data.get("seed"),
                             **({"limits": limits} if limits else {}))
    scenario.time = time_range(stage)
    rows = {p: i for i, p in enumerate(scenario.agents.path)}
    # Deactivated in the shot: out of sight for every camera (their rows stay, at the origin).
    for path in _deactivated(stage, rows):
        scenario.agents.visible[rows[path]] = False
    # Events as the crowd layer and the scenario hold them, without the cameras layer being replaced.
    for layer in stage.GetLayerStack(includeSessionLayers=False):
        if layer_generator(layer) == "usdcrowd cameras":
            stage.MuteLayer(layer.identifier)
    events = read_events(stage, rows, scenario.time)
    detected_now = not any(not e.authored for e in events)
    root = stage.GetDefaultPrim()
    det = EventDetector(scenario.agents.character_type, scenario.agents.visible, scenario.time.fps,
                        scope=f"{root.GetPath()}/Events" if root else "/Events") if detected_now else None
    # The crowd is read back a window at a time; its positions wait on disk for the cameras.
    positions = FrameStore(len(scenario.agents), folder=Path(shot_path).parent)
    with frame_progress(scenario.time.n_frames, "read crowd", progress) as bar:
        for frames in _crowd_windows(stage, scenario, rows, shot_path):
            position = frames.position.astype(np.float32)
            if frames.present is not None:                      # NaN where someone is not in the scene
                position[~frames.present] = np.nan
            positions.append(position)
            if det is not None:
                det.feed(frames)
            bar.update(len(frames.times))
    if det is not None:
        events = model.EventTable([e for e in events if e.authored] + list(det.finish()) + layer_events(
            scenario.fields, positions, scenario.time.codes, scenario.agents.visible, det.scope))
    default_prim = root.GetName() if root else ""
    return ShotCrowd(shot_path, Path(shot_path).parent, scenario, positions, events, detected_now, default_prim,
                     stage_frame(stage), ParentSpace(stage, scenario.time.codes))


# Frames read back at a time: about this many agent-frames (reading takes
# about 650 bytes each while the skeleton is inverted), at most READ_WINDOW.
READ_AGENT_FRAMES = 400_000
READ_WINDOW = 512


def _crowd_windows(stage, scenario: model.Scenario, rows: dict[str, int], shot_path: str):
    """The shot's crowd in consecutive windows of frames (memory bounded in the shot's length), scenario rows."""
    from ..scenario.crowd import read_crowd

    t = scenario.time
    window = min(READ_WINDOW, max(48, READ_AGENT_FRAMES // max(1, len(rows))))
    order = None
    for start in range(0, t.n_frames, window):
        a, b = t.start + start, t.start + min(start + window, t.n_frames) - 1
        frames, info = read_crowd(stage, frames=(a, b))
        if order is None:
            order = _scenario_rows(info.path, rows, shot_path, _deactivated(stage, rows))
        yield _reorder(frames, order, len(rows))


def _deactivated(stage, rows: dict[str, int]) -> set[str]:
    """Scenario agents the shot's stronger layers deactivated (a layout artist's edit)."""
    return {p for p in rows if (prim := stage.GetPrimAtPath(p)) and not prim.IsActive()}


def _scenario_rows(paths: list[str], rows: dict[str, int], shot_path: str, deactivated=frozenset()) -> np.ndarray:
    """Scenario row of each agent read from the shot; the two must hold the same agents, except those
    the shot deactivated."""
    order = np.array([rows.get(p, -1) for p in paths])
    if len(order) == 0 or (order < 0).any():
        missing = [p for p, r in zip(paths, order) if r < 0][:1]
        raise StageError(f"the shot's crowd does not match its scenario (agent {missing[0] if missing else '?'} "
                         f"unknown)" if missing else "the shot's crowd layer holds no agents", file=shot_path)
    if len(set(order.tolist())) != len(rows) - len(deactivated):
        absent = sorted(set(rows) - set(paths) - set(deactivated))[:1]
        raise StageError(f"the shot's crowd does not match its scenario (agent {absent[0] if absent else '?'} "
                         f"is not in the shot; simulate again)", file=shot_path)
    return order


def _reorder(frames: model.CrowdFrames, order: np.ndarray, n: int) -> model.CrowdFrames:
    """The frames with their per-agent arrays moved to scenario rows ``order``."""
    def move(a):
        out = np.zeros((a.shape[0], n) + a.shape[2:], a.dtype)
        out[:, order] = a
        return out

    path_method = np.zeros(n, np.int8)
    path_method[order] = frames.path_method
    return model.CrowdFrames(frames.times, move(frames.position), move(frames.heading), move(frames.velocity),
                             move(frames.behavior), move(frames.anim_class), move(frames.anim_phase),
                             move(frames.health), move(frames.look_at), path_method,
                             None if frames.present is None else move(frames.present))


def refilm_shot(shot_path: str | os.PathLike, count: int | None = None, static: int = 0,
                seed: int | None = None, progress: bool = True, limits=None) -> tuple[str, list[model.CameraTrack], ShotCrowd]:
    """Run the cameras again on an existing shot and replace its cameras.usda atomically.

    The crowd layer, the scenario and any stronger layer are not touched.
    Events are detected (and written beside the cameras) only when the crowd
    layer has none.
    """
    from .pipeline import film_cameras
    from ..usd.cameras import write_camera_tracks
    from ..usd.events import author_events

    check_camera_count((count or 0) + static, "--count and --static")
    sc = load_shot(shot_path, progress=progress, limits=limits)
    tracks = film_cameras(sc.scenario, sc.positions, sc.events, sc.default_prim, progress, count=count,
                          static=static, seed=seed)
    writer = None
    if sc.detected_now:
        def writer(layer):
            author_events(layer, sc.events, sc.scenario.agents.path, sc.scenario.agents.agent_id, sc.frame,
                          parents=sc.parents)
    path = write_camera_tracks(sc.out_dir, tracks, sc.frame, sc.default_prim, sc.scenario.time,
                               defined=set(sc.scenario.cameras.path),
                               extra={"seed": int(sc.scenario.seed if seed is None else seed),
                                      "events": len(sc.events)}, events_writer=writer, keep_toric=True,
                               parents=sc.parents)
    return path, tracks, sc


# ------------------------------------------------------------------ metrics
def evaluate_shot(shot_path: str | os.PathLike, out_dir: str | os.PathLike, counts=(4, 8), seed: int | None = None,
                  progress: bool = True, limits=None) -> dict:
    """Seed 000's evaluation (sections 5.3 and 5.4) on a shot: N autonomous vs N static cameras.

    Writes one CSV per figure (per-frame series), summary.csv, and the plots
    ``activity_N.png`` (Figures 12 and 13) and ``viewed_N.png`` (14 and 15).

    Also measures how well the autonomous cameras frame what they track
    (``tracking_N.csv``, per camera; :mod:`usdcrowd.cameras.tracking_quality`) and
    shows it (``tracking_gallery.png``, with OpenGL).

    Returns
    -------
    dict
        ``{N: {"autonomous": summary, "static": summary, "tracking": pooled tracking quality}}``,
        and the first N's ``"gallery"`` where one was drawn.
    """
    from tqdm import tqdm

    from ..atomic import atomic_path, output_dir
    from ..cameras.metrics import active_mask, coverage
    from ..cameras.overview import crowd_summary
    from .pipeline import film_cameras
    from .plots import coverage_plot

    from ..cameras.tracking_quality import pooled, tracking_quality

    for n in counts:
        check_camera_count(n, f"--counts {n}")
    sc = load_shot(shot_path, progress=progress, limits=limits)
    tracking, gallery = {}, None
    out = output_dir(out_dir, "metrics")
    active = active_mask(sc.events, sc.scenario.time.codes, len(sc.scenario.agents))
    visible = sc.scenario.agents.visible
    summary = crowd_summary(sc.positions, visible)
    results = {}
    # One bar over the steps, named after the one running ("metrics 4 autonomous"); the filming's own
    # frame bar shows below it.
    with tqdm(total=3 * len(counts), desc="metrics", unit="step", disable=not progress, leave=False,
              dynamic_ncols=True) as steps:
        for n in counts:
            steps.set_description(f"metrics {n} autonomous")
            tracks = film_cameras(sc.scenario, sc.positions, sc.events, sc.default_prim, progress, count=n, static=0,
                                  seed=seed, summary=summary)
            agents = [t for t in tracks if t.state is not None]
            series = {"autonomous": coverage(agents, sc.positions, active, visible, obstacles=sc.scenario.obstacles,
                                        overhead=sc.scenario.overhead)}
            quality = tracking_quality(agents, sc.positions, sc.events, visible, sc.scenario.obstacles,
                                       sc.scenario.time.fps, overhead=sc.scenario.overhead, heights=sc.scenario.agents.height)
            tracking[n] = pooled(quality)
            _write_tracking_csv(out / f"tracking_{n}.csv", quality)
            if n == counts[0]:
                gallery = _tracking_gallery(sc.shot, out / "tracking_gallery.png", agents, quality, progress)
            steps.update(1)
            steps.set_description(f"metrics {n} static")
            for kind, where in (("static", "shot"), ("static_start", "start")):
                tracks = film_cameras(sc.scenario, sc.positions, sc.events, sc.default_prim, False, count=0,
                                      static=n, seed=seed, summary=summary, static_from=where)
                series[kind] = coverage([t for t in tracks if t.state is None and "/Static" in t.path],
                                        sc.positions, active, visible, obstacles=sc.scenario.obstacles,
                                        overhead=sc.scenario.overhead)
            steps.update(1)
            steps.set_description(f"metrics {n} plots")
            results[n] = {k: s.summary() for k, s in series.items()}
            for name, column in (("activity", "active_share"), ("viewed", "viewed_share")):
                _write_series_csv(out / f"{name}_{n}.csv", series)
                coverage_plot(series, column, n, out / f"{name}_{n}.png", sc.scenario.time.fps)
            steps.update(1)
    for n in counts:
        results[n]["tracking"] = tracking[n]
    if gallery:
        results[counts[0]]["gallery"] = gallery
    with atomic_path(out / "summary.csv") as tmp, open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        keys = list(results[counts[0]]["autonomous"].keys())
        w.writerow(["cameras", "kind"] + keys)
        for n in counts:
            for kind in ("autonomous", "static", "static_start"):
                w.writerow([n, kind] + [f"{results[n][kind][k]:.6g}" for k in keys])
    return results


def _write_series_csv(path, series: dict) -> None:
    """The autonomous and static cameras' per-frame scores side by side (Figures 12 to 15's data)."""
    from ..atomic import atomic_path

    with atomic_path(path) as tmp, open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["time_code"] + [f"{kind}_{col}" for kind in series
                                    for col in ("score_active", "score_idle", "active", "active_viewed")])
        times = next(iter(series.values())).times
        for k in range(len(times)):
            w.writerow([f"{times[k]:g}"] + [v for s in series.values() for v in (
                f"{s.score_active[k]:.6g}", f"{s.score_idle[k]:.6g}", int(s.n_active[k]), int(s.n_active_viewed[k]))])


def _write_tracking_csv(path, quality) -> None:
    """One row per camera agent: how well it framed what it tracked (:mod:`usdcrowd.cameras.tracking_quality`)."""
    from ..atomic import atomic_path

    keys = ["tracking_frames", "settled_frames", "framed", "blank", "walled", "mean_share", "median_size", "takes",
            "never_framed", "median_seconds_to_frame"]
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["camera"] + keys)
        for q in quality:
            s = q.summary()
            w.writerow([q.camera] + [f"{s[k]:.6g}" if isinstance(s[k], float) else s[k] for k in keys])


def _tracking_gallery(shot: str, out_png, tracks, quality, progress: bool, per_camera: int = 4):
    """Settled tracking frames of each camera agent, labelled with what they show; None without OpenGL."""
    from ..core.errors import UsdcrowdError
    from ..core.view import CameraView

    picks = []
    for tr, q in zip(tracks, quality):
        frames = np.flatnonzero(q.settled & ~np.isnan(q.share))
        for i in frames[np.unique(np.linspace(0, len(frames) - 1, per_camera).round().astype(int))] if len(
                frames) else []:
            picks.append((tr, q, int(i)))
    if not picks:
        return None
    try:
        from ..render.preview.output import contact_sheet, write_png
        from ..render.preview.renderer import PreviewRenderer

        r = PreviewRenderer(shot, 480, 270)
    except (ImportError, UsdcrowdError):
        return None                     # no OpenGL here: the numbers stand without their picture
    try:
        thumbs, labels = [], []
        for tr, q, i in picks:
            view = CameraView(tr.path, float(tr.times[i]), tr.cam_to_world[i], float(tr.focal_length[i]),
                              tr.horizontal_aperture, tr.vertical_aperture, tr.near, tr.far)
            thumbs.append(r.render(float(tr.times[i]), view).color)
            labels.append(f"{tr.path.rsplit('/', 1)[-1]} {tr.times[i]:g} {q.event[i].rsplit('/', 1)[-1]}: "
                          f"{q.share[i]:.0%} visible, {q.size[i]:.0%} tall")
    finally:
        r.release()
    return write_png(contact_sheet(thumbs, labels, columns=per_camera, thumb_width=480), out_png)
