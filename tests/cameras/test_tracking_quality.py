"""Tracking cameras frame their events: measured per frame, held on the harbour and the museum."""

from __future__ import annotations

import csv
import shutil

import numpy as np
import pytest

from usdcrowd.cameras.tracking_quality import SETTLE_SECONDS, pooled, tracking_quality
from usdcrowd.cli import main
from usdcrowd.core import model
from usdcrowd.core.view import look_at

FPS = 24.0


def _run(*argv) -> int:
    return int(main([str(a) for a in argv]) or 0)


def test_takes_settling_and_blank_frames_are_counted_frame_by_frame():
    """A camera takes a pair at frame 10 looking away, turns to it at frame 40, and a wall hides it
    from frame 100 to 119."""
    t = 150
    times = np.arange(1, t + 1, dtype=np.float64)
    pos = np.zeros((t, 2, 3))
    pos[:, 0, :2], pos[:, 1, :2] = [10.0, -0.5], [10.0, 0.5]
    ev = model.Event("/E/Pair", model.code(model.EVENT_KINDS, "interaction"), 1.0, float(t), np.arange(2, dtype=np.int32),
                     times.copy(), np.ones((t, 2), bool), np.zeros((t, 3)), np.ones(t))
    away = look_at([0.0, 0.0, 1.6], [0.0, 10.0, 1.2])[0]
    toward = look_at([0.0, 0.0, 1.6], [10.0, 0.0, 1.2])[0]
    mats = np.stack([away if k < 39 else toward for k in range(t)])
    tracked = ["" if k < 9 else "/E/Pair" for k in range(t)]
    track = model.CameraTrack("/Cam", times, mats, np.full(t, 35.0), 36.0, 20.25, 0.1, 500.0,
                              np.array([0 if k < 9 else 1 for k in range(t)], np.int8), tracked)
    wall = model.Obstacles(["/Wall"], [np.array([[4.8, -3.0], [5.2, -3.0], [5.2, 3.0], [4.8, 3.0]])], np.array([3.0]))
    # The wall stands only from frame 100 to 119: two runs, one before, one with it, spliced.
    clear = tracking_quality([track], pos, model.EventTable([ev]), np.ones(2, bool), model.Obstacles.empty(), FPS)[0]
    walled = tracking_quality([track], pos, model.EventTable([ev]), np.ones(2, bool), wall, FPS)[0]
    share = np.where((np.arange(t) >= 99) & (np.arange(t) < 119), walled.share, clear.share)
    assert np.isnan(clear.share[:9]).all() and (clear.share[9:39] == 0).all() and (clear.share[39:] == 1).all()
    assert (walled.share[39:] == 0).all()
    # Looking away, and behind the wall, the picture shows no one of the pair: walled.
    assert clear.walled[9:39].all() and not clear.walled[39:].any() and walled.walled[39:].all()
    assert clear.takes == [("/E/Pair", 10.0, pytest.approx(30 / FPS))]
    settled = clear.settled
    assert not settled[:9 + int(SETTLE_SECONDS * FPS)].any() and settled[9 + int(SETTLE_SECONDS * FPS):].all()
    s = clear.summary()
    assert s["settled_frames"] == t - 9 - 48 and s["framed"] == 1.0 and s["blank"] == 0.0
    q = clear
    q.share = share
    q.walled = (np.arange(t) >= 99) & (np.arange(t) < 119)
    s = q.summary()
    assert s["blank"] == pytest.approx(20 / (t - 57)) and s["framed"] == pytest.approx(1 - 20 / (t - 57))
    assert s["walled"] == pytest.approx(20 / (t - 57))
    assert pooled([q, q])["settled_frames"] == 2 * (t - 57)


def test_a_passer_by_in_front_of_the_event_is_a_blank_frame_but_not_walled():
    """A third person stands on the line from the camera to a pair: none of the pair is visible (blank),
    but the picture shows a person in front of them, not only scenery."""
    t = 60
    times = np.arange(1, t + 1, dtype=np.float64)
    pos = np.zeros((t, 3, 3))
    pos[:, 0, :2], pos[:, 1, :2], pos[:, 2, :2] = [10.0, -0.1], [10.0, 0.1], [3.0, 0.0]
    ev = model.Event("/E/Pair", model.code(model.EVENT_KINDS, "interaction"), 1.0, float(t), np.arange(2, dtype=np.int32),
                     times.copy(), np.ones((t, 2), bool), np.zeros((t, 3)), np.ones(t))
    mats = np.repeat(look_at([0.0, 0.0, 1.2], [10.0, 0.0, 1.2]), t, axis=0)
    track = model.CameraTrack("/Cam", times, mats, np.full(t, 35.0), 36.0, 20.25, 0.1, 500.0,
                              np.ones(t, np.int8), ["/E/Pair"] * t)
    q = tracking_quality([track], pos, model.EventTable([ev]), np.ones(3, bool), model.Obstacles.empty(), FPS)[0]
    assert (q.share == 0).all() and not q.walled.any()
    s = q.summary()
    assert s["blank"] == 1.0 and s["walled"] == 0.0


@pytest.fixture(scope="module")
def harbour_metrics(simulated_harbour, tmp_path_factory):
    """``usdcrowd metrics --counts 4`` and ``usdcrowd cameras --count 4`` on a copy of the harbour."""
    base = tmp_path_factory.mktemp("harbour_metrics")
    shutil.copytree(simulated_harbour.parent, base / "harbour")
    shot = base / "harbour" / "shot" / "shot.usda"
    assert _run("metrics", shot, "-o", base / "metrics", "--counts", "4", "--no-progress") == 0
    assert _run("cameras", shot, "--count", "4", "--no-progress") == 0
    return shot, base / "metrics"


def _rows(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def _check_targets(rows):
    """At least half the event's people visible in >= 80 % of settled frames, every camera; frames with
    nobody visible at most 5 % over all cameras (one run: a steering run is chaotic, and another
    machine's rounding is another run; the seeds test below holds the typical run to less)."""
    measured = [r for r in rows if int(r["settled_frames"]) >= 48]
    assert len(measured) >= 2, rows
    for r in measured:
        assert float(r["framed"]) >= 0.8, r
    settled = np.array([int(r["settled_frames"]) for r in measured])
    blank = np.array([float(r["blank"]) for r in measured])
    assert (blank * settled).sum() / settled.sum() <= 0.05, rows


def test_harbour_tracking_cameras_are_rarely_blank_whatever_the_seed(simulated_harbour):
    """Five runs of 4 camera agents on the harbour (seeds 0-4 of their wandering): in the median run no
    settled tracking frame shows none of the event's people, nor only scenery or ground; in none more
    than 1 % blank or 0.5 % walled. (Measured: 0 and 0 in all eight runs of seeds 0-7; before cameras
    backed away from people walking at them and panned round as a camera head does, the worst run was
    3.1 %. Another machine's rounding is another chaotic run: hence bounds, not zeros, per run.)"""
    from usdcrowd.cameras.overview import crowd_summary
    from usdcrowd.jobs.filming import load_shot
    from usdcrowd.jobs.pipeline import film_cameras

    sc = load_shot(simulated_harbour / "shot.usda", progress=False)
    visible = sc.scenario.agents.visible
    summary = crowd_summary(sc.positions, visible)
    blank, walled = [], []
    for seed in range(5):
        tracks = film_cameras(sc.scenario, sc.positions, sc.events, sc.default_prim, False, count=4, static=0,
                              seed=seed, summary=summary)
        quality = tracking_quality([t for t in tracks if t.state is not None], sc.positions, sc.events, visible,
                                   sc.scenario.obstacles, FPS, overhead=sc.scenario.overhead,
                                   heights=sc.scenario.agents.height)
        p = pooled(quality)
        blank.append(p["blank"])
        walled.append(p["walled"])
    assert np.median(blank) == 0.0 and max(blank) <= 0.01, blank
    assert np.median(walled) == 0.0 and max(walled) <= 0.005, walled


def test_harbour_tracking_cameras_frame_their_event_after_two_seconds(harbour_metrics):
    shot, metrics = harbour_metrics
    _check_targets(_rows(metrics / "tracking_4.csv"))
    assert (metrics / "tracking_gallery.png").stat().st_size > 0


def test_framed_frames_show_the_events_people_in_the_preview_id_pass(harbour_metrics):
    """Independent of the sight lines: the OpenGL id pass of each camera agent at settled tracking
    frames has pixels of at least half the tracked event's people in nearly every one."""
    from pxr import Usd

    from usdcrowd.render.preview.renderer import PreviewRenderer
    from usdcrowd.scenario.shot_scene import ShotScene

    shot, _ = harbour_metrics
    stage = Usd.Stage.Open(str(shot))
    scene = ShotScene(shot)
    framed, checked = 0, 0
    r = PreviewRenderer(shot, 640, 360)
    try:
        for cam in [p for p in stage.Traverse() if p.GetAttribute("crowd:camera:state").HasValue()]:
            tracked = cam.GetAttribute("crowd:camera:trackedEvent")
            times = scene.time_codes
            settled = []
            for t in times:
                e = tracked.Get(t)
                if e and all(tracked.Get(t - k) == e for k in range(0, int(SETTLE_SECONDS * FPS) + 1)
                             if t - k >= times[0]) and t - times[0] >= SETTLE_SECONDS * FPS:
                    settled.append(t)
            for t in settled[::max(1, len(settled) // 6)][:6]:
                event = stage.GetPrimAtPath(tracked.Get(t))
                members = set(event.GetAttribute("crowd:memberIds").Get(t))
                poses = scene.agents(t)
                shown = [i for i in members if poses.visible[list(poses.agent_ids).index(i)]]
                ids = np.bincount(r.render(float(t), str(cam.GetPath())).ids.ravel().astype(np.int64),
                                  minlength=max(int(max(poses.agent_ids)), 1) + 1)
                if shown:
                    checked += 1
                    framed += np.mean([ids[i] > 0 for i in shown]) >= 0.5
    finally:
        r.release()
    assert checked >= 8 and framed / checked >= 0.9, (framed, checked)


def test_museum_tracking_cameras_frame_their_event(tmp_path):
    from tests.helpers.shots import cli_museum_shot

    _, shot = cli_museum_shot(tmp_path, 40, 240)
    assert _run("metrics", shot / "shot.usda", "-o", tmp_path / "metrics", "--counts", "4", "--no-progress") == 0
    rows = _rows(tmp_path / "metrics" / "tracking_4.csv")
    measured = [r for r in rows if int(r["settled_frames"]) >= 24]
    assert measured, rows
    for r in measured:
        assert float(r["framed"]) >= 0.8 and float(r["blank"]) <= 0.01, r
