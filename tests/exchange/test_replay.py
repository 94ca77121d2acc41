"""`usdcrowd replay TRAJ -o SHOT/`: recorded or peer trajectories walked by usdcrowd's people.

The trajectories come from JuPedSim itself (run in its own venv inside the
test, writing its SQLite database) and from an ETH/UCY text file written
here; the shot is read back with plain usd-core (UsdSkel, no usdcrowd
imported) and with PedPy (own venv) after `export --trajectories`.
"""

from __future__ import annotations

import json
import sqlite3
import subprocess
import textwrap

import numpy as np
import pytest

from usdcrowd.cli import main

from tests.helpers.plain_usd import people_as_plain_usd_sees_them
from tests.helpers.venvs import jupedsim_python, pedpy_python

# JuPedSim: a 24 x 4 m corridor walked to an exit at its far end; four people start, two more come in
# after 2 s and two after 4 s; each is removed as they reach the exit. 100 steps a second, every fourth
# written: 25 frames per second.
CORRIDOR_RUN = """
    import pathlib, sys
    import jupedsim as jps
    import shapely
    area = shapely.Polygon([(0, 0), (24, 0), (24, 4), (0, 4)])
    writer = jps.SqliteTrajectoryWriter(output_file=pathlib.Path(sys.argv[1]), every_nth_frame=4)
    sim = jps.Simulation(model=jps.CollisionFreeSpeedModel(), geometry=area, dt=0.01, trajectory_writer=writer)
    exit_ = sim.add_exit_stage(shapely.Polygon([(22.5, 0), (24, 0), (24, 4), (22.5, 4)]))
    journey = sim.add_journey(jps.JourneyDescription([exit_]))
    def add(x, y, v):
        sim.add_agent(jps.CollisionFreeSpeedModelAgentParameters(journey_id=journey, stage_id=exit_,
                      position=(x, y), desired_speed=v, radius=0.2))
    for k, (x, y) in enumerate([(1, 1), (2, 2), (1, 3), (3, 1.2)]):
        add(x, y, 1.0 + 0.15 * k)
    while sim.agent_count() > 0 and sim.iteration_count() < 4000:
        if sim.iteration_count() in (200, 400):
            add(1, 2, 1.3)
            add(2.2, 3, 1.1)
        sim.iterate()
"""

def _run(python: str, script: str, *args) -> dict | None:
    out = subprocess.run([python, "-c", textwrap.dedent(script), *map(str, args)], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-3000:]
    lines = out.stdout.strip().splitlines()
    return json.loads(lines[-1]) if lines else None


def _plain_usd(shot) -> dict:
    return people_as_plain_usd_sees_them(shot)


def _file_rows(db) -> dict:
    """{(id, frame): (x, y)} as the database holds them (sqlite3, no usdcrowd)."""
    with sqlite3.connect(db) as con:
        return {(int(i), int(f)): (x, y) for i, f, x, y in con.execute(
            "SELECT id, frame, pos_x, pos_y FROM trajectory_data")}


@pytest.fixture(scope="module")
def corridor_database(tmp_path_factory):
    """JuPedSim's own trajectory database of the corridor run (CORRIDOR_RUN)."""
    python = jupedsim_python()
    db = tmp_path_factory.mktemp("jupedsim") / "corridor.sqlite"
    _run(python, CORRIDOR_RUN, db)
    return db


@pytest.fixture(scope="module")
def replayed_corridor(corridor_database, tmp_path_factory):
    """The corridor run replayed into a shot, two camera agents."""
    out = tmp_path_factory.mktemp("replayed") / "shot"
    assert main(["replay", str(corridor_database), "-o", str(out), "--cameras", "2", "--no-progress"]) == 0
    return out


@pytest.fixture(scope="module")
def corridor_as_plain_usd_sees_it(replayed_corridor):
    return _plain_usd(replayed_corridor / "shot.usda")


def test_every_row_jupedsim_wrote_is_where_the_replayed_person_stands(corridor_database,
                                                                        corridor_as_plain_usd_sees_it):
    """Point for point: each (id, frame) row of JuPedSim's database is that person's hips at time code
    frame + 1, to a millimetre, shown; at every time code without a row the person is hidden."""
    rows = _file_rows(corridor_database)
    read = corridor_as_plain_usd_sees_it
    assert read["fps"] == 25.0 and read["first"] == 1.0
    people = read["people"]
    assert sorted(people) == sorted({i for i, _ in rows}) and len(people) == 8
    checked = hidden = 0
    for person, got in people.items():
        for k, (shown, x, y, *_rest) in enumerate(got["rows"]):
            want = rows.get((person, k))
            if want is None:
                assert not shown, (person, k)
                hidden += 1
                continue
            assert shown and np.hypot(x - want[0], y - want[1]) < 1e-3, (person, k, (x, y), want)
            checked += 1
    assert checked == len(rows) == 3380 and hidden > 300


def test_replayed_people_face_and_look_the_way_they_walk(corridor_database, corridor_as_plain_usd_sees_it):
    """The hips face the direction of travel (taken here from the database's own positions, over 0.2 s)
    within 10 degrees while people walk, and the head looks within 20 degrees of it."""
    rows = _file_rows(corridor_database)
    hips_off, head_off = [], []
    for person, got in corridor_as_plain_usd_sees_it["people"].items():
        for k, (shown, x, y, fx, fy, hx, hy) in enumerate(got["rows"]):
            a, b = rows.get((person, k - 5)), rows.get((person, k + 5))
            if not shown or a is None or b is None:
                continue
            travel = np.subtract(b, a)
            if np.linalg.norm(travel) < 0.4 * 0.4:         # under 0.4 m/s: standing, not walking
                continue
            hips_off.append(_angle_between(travel, (fx, fy)))
            head_off.append(_angle_between(travel, (hx, hy)))
    assert len(hips_off) > 2000
    assert np.percentile(hips_off, 99) < 10.0, np.percentile(hips_off, 99)
    assert np.percentile(head_off, 99) < 20.0, np.percentile(head_off, 99)


def _angle_between(u, v) -> float:
    """Unsigned angle between two ground directions, degrees."""
    return abs(np.degrees(np.arctan2(u[0] * v[1] - u[1] * v[0], u[0] * v[0] + u[1] * v[1])))


ETH_ROWS = """\
0\t1\t0.00\t0.00
10\t1\t0.50\t0.10
20\t1\t1.00\t0.30
30\t1\t1.50\t0.30
10\t2\t5.00\t5.00
20\t2\t5.00\t4.40
170\t2\t5.00\t2.00
180\t2\t5.00\t1.40
40\t3\t-2.00\t1.00
70\t3\t-1.00\t1.00
80\t3\t-0.60\t1.00
"""


def test_eth_ucy_rows_are_interpolated_and_a_long_gap_is_leaving_and_coming_back(tmp_path):
    """An ETH/UCY file (frame id x y, a row every 10 video frames at 25 per second): the shot runs at 25
    fps from the file's first frame; between rows people walk the straight line between them (here
    np.interp), a 1.2 s gap is walked through, a 6 s gap (over --max-gap 2 s) is leaving and coming back;
    before the first row and after the last the person is hidden."""
    traj = tmp_path / "students.txt"
    traj.write_text(ETH_ROWS)
    assert main(["replay", str(traj), "-o", str(tmp_path / "shot"), "--cameras", "0", "--no-progress"]) == 0
    read = _plain_usd(tmp_path / "shot" / "shot.usda")
    assert read["fps"] == 25.0
    table = np.array([[float(v) for v in line.split()] for line in ETH_ROWS.splitlines()])
    for person, got in read["people"].items():
        mine = table[table[:, 1] == person]
        frames = np.arange(len(got["rows"]))
        shown = got["rows"][:, 0].astype(bool)
        inside = (frames >= mine[0, 0]) & (frames <= mine[-1, 0])
        gaps = [(a, b) for a, b in zip(mine[:-1, 0], mine[1:, 0]) if b - a > 2.0 * 25]
        for a, b in gaps:
            inside &= ~((frames > a) & (frames < b))
        np.testing.assert_array_equal(shown, inside, err_msg=f"person {person}")
        want = np.stack([np.interp(frames, mine[:, 0], mine[:, 2]), np.interp(frames, mine[:, 0], mine[:, 3])], 1)
        np.testing.assert_allclose(got["rows"][shown, 1:3], want[shown], atol=1e-3, err_msg=f"person {person}")
    assert not read["people"][2]["rows"][100, 0] and read["people"][3]["rows"][55, 0]


def test_a_replayed_shot_exports_the_rows_it_was_replayed_from(corridor_database, replayed_corridor, tmp_path):
    """`export --trajectories` of the replayed corridor, read by PedPy (own venv, no extra argument), holds
    JuPedSim's rows (same ids and frames, positions to a millimetre, 25 fps); replaying that export again
    takes each person's height from its Z column (the top of the head) to 2 cm."""
    out = tmp_path / "back.txt"
    assert main(["export", str(replayed_corridor / "shot.usda"), "--trajectories", str(out), "--no-progress"]) == 0
    read = _run(pedpy_python(), f"""
        import json, pathlib
        import pedpy
        t = pedpy.load_trajectory(trajectory_file=pathlib.Path({str(out)!r}))
        print(json.dumps({{"fps": t.frame_rate, "rows": t.data[["id", "frame", "x", "y"]].values.tolist()}}))
    """)
    assert read["fps"] == 25.0
    back = {(int(i), int(f)): (x, y) for i, f, x, y in read["rows"]}
    rows = _file_rows(corridor_database)
    assert set(back) == set(rows)
    assert max(np.hypot(back[k][0] - rows[k][0], back[k][1] - rows[k][1]) for k in rows) < 1e-3
    # Another seed: heights drawn again would differ.
    assert main(["replay", str(out), "-o", str(tmp_path / "again"), "--cameras", "0", "--seed", "5",
                 "--no-progress"]) == 0
    first = _plain_usd(replayed_corridor / "shot.usda")["people"]
    again = _plain_usd(tmp_path / "again" / "shot.usda")["people"]
    for person in first:
        assert abs(again[person]["height"] - first[person]["height"]) < 0.02, person


def test_events_cameras_and_ground_truth_leave_out_people_not_there(corridor_database, replayed_corridor, tmp_path):
    """On the replayed corridor the MOT ground truth of a final render lists, at each frame, exactly the ids
    JuPedSim has at that frame; `usdcrowd cameras` films the shot again; every detected event's people
    were in the corridor whenever the event counts them."""
    from usdcrowd.scenario import open_stage
    from usdcrowd.scenario.events import read_events
    from usdcrowd.scenario.stageio import time_range

    rows = _file_rows(corridor_database)
    assert main(["render", str(replayed_corridor / "shot.usda"), "-o", str(tmp_path / "render"), "--frames",
                 "1:401x100", "--resolution", "160x90", "--spp", "1", "--no-progress"]) == 0
    gt = np.loadtxt(tmp_path / "render" / "mot" / "gt" / "gt.txt", delimiter=",", ndmin=2)
    for k, code in enumerate((1, 101, 201, 301, 401), start=1):
        want = sorted(i for i, f in rows if f == code - 1)
        assert sorted(gt[gt[:, 0] == k, 1].astype(int)) == want, code
    assert main(["cameras", str(replayed_corridor / "shot.usda"), "--no-progress"]) == 0
    stage = open_stage(str(replayed_corridor / "shot.usda"))
    paths = {int(p.GetAttribute("crowd:agentId").Get()): str(p.GetPath()) for p in stage.Traverse()
             if p.HasAttribute("crowd:agentId")}
    ids = sorted(paths)
    events = read_events(stage, {paths[i]: r for r, i in enumerate(ids)}, time_range(stage))
    assert len(events) > 0
    for e in events:
        for t, active in zip(e.times, e.active):
            for member in e.members[active]:
                assert (ids[member], int(t) - 1) in rows, (e.path, t, ids[member])


@pytest.mark.parametrize("content, extra, words", [
    ("", [], "empty"),
    ("0 1 0.0 0.0\n10 1 x 0.5\n", [], "line 2"),
    ("# ID FR X Y Z\n1 0 0 0 1.7\n1 1 0.1 0 1.7\n", [], "--fps"),
    ("# framerate: 25 fps\n1 0 0 0 1.7\n1 1 0.1 0 1.7\n", ["--fps", "10"], "leave --fps out"),
    ("0 1 0.0 0.0\n0 1 0.5 0.5\n", [], "two rows at frame 0"),
    ("0 1.5 0.0 0.0\n10 1.5 0.5 0.5\n", [], "not a whole number"),
    ("0 1 0.0 0.0\n10 1 1e30 0.5\n20 1 2 2\n", [], "person 1 at frame 10 stands at (1e+30, 0.5) m"),
    ("0 1 0.0 0.0\n10 1 0.5 0.5\n", ["--height-from", "file"], "needs every person's Z"),
])
def test_a_careless_replay_is_one_line_and_writes_no_shot(tmp_path, capsys, content, extra, words):
    """A bad trajectory file (empty, a word for a number, no frame rate, a rate the file contradicts, two
    rows for one person at one frame, a fractional id, a position beyond the scene's extent, heights asked
    of a file without them): one line naming the file, exit 2, not even the shot's folder."""
    traj = tmp_path / "walks.txt"
    traj.write_text(content)
    assert main(["replay", str(traj), "-o", str(tmp_path / "shot"), *extra, "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and words in err and "walks.txt" in err, err
    assert not (tmp_path / "shot").exists()


def test_replayed_people_walk_in_a_dcc_tools_scenery(corridor_database, tmp_path):
    """--scenery places a DCC tool's layer (Y up, centimetres) as `new --scenery` does: the replay's
    scenario has its kiosk at (10, 2) m, 1 m wide, as an obstacle; the people stay on the file's rows."""
    from tests.exchange.test_dcc_scenery import _dcc_box
    from usdcrowd.scenario import load_scenario

    kiosk = tmp_path / "kiosk.usda"
    _dcc_box(kiosk, "Kiosk", "Y", 0.01, 100.0, (1000.0, 50.0, -200.0))
    shot = tmp_path / "shot"
    assert main(["replay", str(corridor_database), "-o", str(shot), "--scenery", str(kiosk), "--cameras", "0",
                 "--no-progress"]) == 0
    obstacles = load_scenario(shot / "replay.usda").obstacles
    assert len(obstacles) == 1
    footprint = obstacles.polygons[0]
    np.testing.assert_allclose(footprint.mean(axis=0), [10.0, 2.0], atol=0.02)
    np.testing.assert_allclose(np.ptp(footprint, axis=0), [1.0, 1.0], atol=0.02)
    people = _plain_usd(shot / "shot.usda")["people"]
    rows = _file_rows(corridor_database)
    for (person, frame), (x, y) in list(rows.items())[::50]:
        assert np.hypot(*(people[person]["rows"][frame, 1:3] - (x, y))) < 1e-3


def test_a_companion_scenario_gives_its_people_scenery_and_cameras(tmp_path):
    """--scenario: the dialogue template's A and C (ids 1, 3) walk the file's rows as themselves (their
    prims, colours and heights); id 7, whom the template lacks, joins a group of its own; the template's B
    and D (ids 2, 4), absent from the file, are switched off (D's group with it), and its two-shot camera
    and dialogue event come into the shot."""
    from usdcrowd.scenario import load_scenario, open_stage

    companion = tmp_path / "dialogue.usda"
    assert main(["new", "dialogue", "-o", str(companion)]) == 0
    traj = tmp_path / "talk.txt"
    traj.write_text("".join(f"{k}\t{i}\t{x:.3f}\t{y:.3f}\n" for k in range(0, 200, 10) for i, x, y in (
        (1, -0.75 + 0.002 * k, 2.0), (3, -8.0 + 0.04 * k, 5.0), (7, -6.0 + 0.05 * k, -3.0))))
    shot = tmp_path / "shot"
    assert main(["replay", str(traj), "-o", str(shot), "--scenario", str(companion), "--no-progress"]) == 0
    sc = load_scenario(shot / "replay.usda")
    by_id = {int(i): p for i, p in zip(sc.agents.agent_id, sc.agents.path)}
    assert by_id == {1: "/World/Crowd/Pair/A", 3: "/World/Crowd/Walkers/Left/C",
                     7: "/World/Crowd/People/Person_7"}
    template = open_stage(str(companion))
    stage = open_stage(str(shot / "shot.usda"))
    for path in (by_id[1], by_id[3]):
        for name in ("crowd:color", "crowd:height"):
            assert stage.GetPrimAtPath(path).GetAttribute(name).Get() == \
                template.GetPrimAtPath(path).GetAttribute(name).Get(), (path, name)
    assert not stage.GetPrimAtPath("/World/Crowd/Pair/B").IsActive()
    assert not stage.GetPrimAtPath("/World/Crowd/Walkers/Right").IsActive()
    people = _plain_usd(shot / "shot.usda")["people"]
    assert sorted(people) == [1, 3, 7]
    np.testing.assert_allclose(people[7]["rows"][100, 1:3], (-6.0 + 0.05 * 100, -3.0), atol=1e-3)
    assert stage.GetPrimAtPath("/World/Cameras/TwoShot") and stage.GetPrimAtPath("/World/Events/Dialogue")


def test_replayed_motion_does_not_depend_on_the_window_it_is_made_in(tmp_path):
    """The frames are made a window at a time: windows of 7 frames give what one window of the whole
    recording gives (positions, headings, velocities, the walk cycle, gaze, who is present)."""
    from usdcrowd.exchange.recorded_tracks import read_tracks
    from usdcrowd.exchange.replay_motion import ReplayMotion, TrackSampler

    traj = tmp_path / "students.txt"
    traj.write_text(ETH_ROWS)
    sampler = TrackSampler(read_tracks(traj), 25.0)
    height = np.array([1.7, 1.8, 1.6])
    whole = next(ReplayMotion(sampler, 1.0, height).chunks(sampler.n_frames))
    parts = list(ReplayMotion(sampler, 1.0, height).chunks(7))
    for name in ("times", "position", "heading", "velocity", "anim_class", "anim_phase", "look_at", "present"):
        joined = np.concatenate([getattr(p, name) for p in parts])
        np.testing.assert_allclose(joined, getattr(whole, name), atol=1e-5, err_msg=name)


def test_ids_from_zero_are_shifted_to_start_at_one_and_the_shift_is_recorded(tmp_path, capsys):
    """USD agent ids and MOT ids start at 1: a file counting people from 0 is replayed with every id + 1,
    said on the command line and recorded in the replay's scenario (idOffset)."""
    traj = tmp_path / "zero.txt"
    traj.write_text("0 0 0.0 0.0\n10 0 0.5 0.0\n0 4 1.0 1.0\n10 4 1.5 1.0\n")
    assert main(["replay", str(traj), "-o", str(tmp_path / "shot"), "--cameras", "0", "--no-progress"]) == 0
    assert "ids shifted by +1" in capsys.readouterr().out
    assert sorted(_plain_usd(tmp_path / "shot" / "shot.usda")["people"]) == [1, 5]
    from pxr import Sdf

    data = Sdf.Layer.FindOrOpen(str(tmp_path / "shot" / "replay.usda")).customLayerData
    assert data["usdcrowd"]["replay"]["idOffset"] == 1


def test_a_pedpy_file_in_centimetres_is_read_in_metres_at_its_frame_rate_or_the_one_asked(tmp_path):
    """PedPy's text with its header ('# framerate: 16', 'x/cm'): positions read in metres, the shot at the
    file's 16 fps; with --shot-fps 32 every other frame lies halfway between two rows."""
    traj = tmp_path / "julich.txt"
    traj.write_text("# framerate: 16 fps\n# ID\tFR\tX/cm\tY/cm\tZ/cm\n"
                    + "".join(f"3\t{k}\t{100 + 10 * k}\t{-50 + 5 * k}\t175\n" for k in range(40)))
    assert main(["replay", str(traj), "-o", str(tmp_path / "a"), "--cameras", "0", "--no-progress"]) == 0
    a = _plain_usd(tmp_path / "a" / "shot.usda")
    assert a["fps"] == 16.0 and len(a["people"][3]["rows"]) == 40
    np.testing.assert_allclose(a["people"][3]["rows"][:, 1:3], np.stack([1.0 + 0.1 * np.arange(40),
                                                                          -0.5 + 0.05 * np.arange(40)], 1),
                               atol=1e-3)
    assert abs(a["people"][3]["height"] - 1.75) < 1e-6
    assert main(["replay", str(traj), "-o", str(tmp_path / "b"), "--shot-fps", "32", "--cameras", "0",
                 "--no-progress"]) == 0
    b = _plain_usd(tmp_path / "b" / "shot.usda")
    assert b["fps"] == 32.0 and len(b["people"][3]["rows"]) == 79
    np.testing.assert_allclose(b["people"][3]["rows"][1::2, 1], 1.05 + 0.1 * np.arange(39), atol=1e-3)


@pytest.mark.parametrize("value, words", [("x", "row 2 is (1, 1, 'x', 0.5, 1.0, 0.0)"),
                                           (None, "not a finite number")])
def test_a_database_row_that_is_no_number_is_one_line(tmp_path, capsys, value, words):
    """SQLite keeps whatever a column is given: a word, or NULL, where a position should be is one line
    naming the file (and the row, for a word), exit 2, no shot folder."""
    db = tmp_path / "typed.sqlite"
    with sqlite3.connect(db) as con:
        con.execute("CREATE TABLE trajectory_data (frame, id, pos_x, pos_y, ori_x, ori_y)")
        con.execute("CREATE TABLE metadata (key TEXT, value TEXT)")
        con.execute("INSERT INTO metadata VALUES ('fps', '10')")
        con.executemany("INSERT INTO trajectory_data VALUES (?, ?, ?, ?, ?, ?)",
                        [(0, 1, 0.0, 0.0, 1.0, 0.0), (1, 1, value, 0.5, 1.0, 0.0)])
    assert main(["replay", str(db), "-o", str(tmp_path / "shot"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and words in err and "typed.sqlite" in err, err
    assert not (tmp_path / "shot").exists()


def test_people_standing_face_the_way_a_jupedsim_database_says(tmp_path):
    """JuPedSim's rows carry an orientation (ori_x, ori_y): someone standing faces it (here +Y, then
    turning to -X half-way), where walking people face their way of walking; without one (0, 0) they
    keep facing the way they last walked, +X."""

    db = tmp_path / "waiting.sqlite"
    with sqlite3.connect(db) as con:
        con.execute("CREATE TABLE trajectory_data (frame INTEGER, id INTEGER, pos_x REAL, pos_y REAL, "
                    "ori_x REAL, ori_y REAL)")
        con.execute("CREATE TABLE metadata (key TEXT, value TEXT)")
        con.executemany("INSERT INTO metadata VALUES (?, ?)", [("version", "2"), ("fps", "25")])
        rows = [(k, 1, 0.0, 0.0, *((0.0, 1.0) if k < 50 else (-1.0, 0.0))) for k in range(100)]
        rows += [(k, 2, 2.0 + 0.05 * min(k, 30), 3.0, 0.0, 0.0) for k in range(100)]
        con.executemany("INSERT INTO trajectory_data VALUES (?, ?, ?, ?, ?, ?)", rows)
    assert main(["replay", str(db), "-o", str(tmp_path / "shot"), "--cameras", "0", "--no-progress"]) == 0
    people = _plain_usd(tmp_path / "shot" / "shot.usda")["people"]
    facing = lambda person, k: np.degrees(np.arctan2(people[person]["rows"][k, 4], people[person]["rows"][k, 3]))  # noqa: E731
    assert abs(facing(1, 20) - 90.0) < 2.0 and abs(abs(facing(1, 80)) - 180.0) < 2.0
    assert abs(facing(2, 10)) < 8.0 and abs(facing(2, 80)) < 2.0        # walking: the hips sway with the stride


def test_someone_coming_back_after_a_gap_walks_at_their_pace_from_the_first_frame(tmp_path):
    """Person 2 of ETH_ROWS leaves at (5, 4.4) and comes back 6 s later at (5, 2.0), walking -Y at 1.5 m/s:
    the replay's velocity on their first frames back is that, not the jump from where they left."""
    from usdcrowd.exchange.recorded_tracks import read_tracks
    from usdcrowd.exchange.replay_motion import ReplayMotion, TrackSampler

    traj = tmp_path / "students.txt"
    traj.write_text(ETH_ROWS)
    sampler = TrackSampler(read_tracks(traj), 25.0)
    frames = next(ReplayMotion(sampler, 1.0, np.full(3, 1.7)).chunks(sampler.n_frames))
    back = 170
    assert not frames.present[back - 1, 1] and frames.present[back, 1]
    np.testing.assert_allclose(frames.velocity[back:back + 5, 1], [[0.0, -1.5]] * 5, atol=1e-3)


def test_a_track_with_the_id_of_a_companions_invisible_leader_is_refused_in_one_line(tmp_path, capsys):
    """The harbour's gang is led by an invisible leader (id 2): a track with that id would walk unseen, so
    the replay refuses it in one line naming the prim, exit 2, and writes no shot."""
    companion = tmp_path / "harbour.usda"
    assert main(["new", "harbour", "-o", str(companion)]) == 0
    capsys.readouterr()
    traj = tmp_path / "walks.txt"
    traj.write_text("0 2 0.0 0.0\n10 2 0.5 0.0\n")
    assert main(["replay", str(traj), "-o", str(tmp_path / "shot"), "--scenario", str(companion),
                 "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "invisible leader" in err and "Tally" in err, err
    assert not (tmp_path / "shot" / "shot.usda").exists()


def test_a_window_of_a_long_track_reads_only_the_rows_around_it():
    """A window's positions and facings come from the rows bracketing its frames, so making a window does not
    cost more as a track grows; they are what interpolating the whole track gives."""
    from usdcrowd.exchange.recorded_tracks import Tracks
    from usdcrowd.exchange.replay_motion import TrackSampler

    m = 5000                                           # one person, a row every 0.4 s, a wavy walk
    frame = np.arange(m, dtype=np.float64) * 10
    xy = np.column_stack([0.5 * np.arange(m), np.sin(np.arange(m) / 7.0)])
    facing = np.linspace(-3.0, 3.0, m)
    tracks = Tracks(np.array([1]), 25.0, frame, np.zeros(m, np.int64), xy, np.full(m, np.nan), "ethucy", "walk.txt",
                    facing)
    sampler = TrackSampler(tracks, 25.0)
    a, b = 30_000, 30_040
    rows = sampler._bracketing(0, np.arange(a, b))
    assert rows.stop - rows.start <= 40 / 10 + 2
    s = tracks.seconds
    at = np.arange(a, b) / 25.0
    np.testing.assert_allclose(sampler.window(a, b)[:, 0], np.column_stack([np.interp(at, s, xy[:, 0]),
                                                                            np.interp(at, s, xy[:, 1])]))
    expected = np.arctan2(np.interp(at, s, np.sin(facing)), np.interp(at, s, np.cos(facing)))
    np.testing.assert_allclose(sampler.facing(a, b)[:, 0], expected, atol=1e-12)


def test_who_is_present_reads_back_as_usd_computes_each_frames_visibility(tmp_path):
    """read_crowd takes presence from the visibility samples (held between them): the same as plain
    usd-core's ComputeVisibility at every frame."""
    from pxr import Usd, UsdGeom

    from usdcrowd.scenario.crowd import read_crowd

    traj = tmp_path / "students.txt"
    traj.write_text(ETH_ROWS)
    shot = tmp_path / "shot"
    assert main(["replay", str(traj), "-o", str(shot), "--cameras", "0", "--no-progress"]) == 0
    frames, info = read_crowd(shot / "shot.usda")
    stage = Usd.Stage.Open(str(shot / "shot.usda"))
    expected = np.array([[UsdGeom.Imageable(stage.GetPrimAtPath(p)).ComputeVisibility(float(t)) != "invisible"
                          for p in info.path] for t in frames.times])
    assert expected.any() and not expected.all()
    np.testing.assert_array_equal(frames.present, expected)
