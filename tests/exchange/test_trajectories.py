"""`usdcrowd export SHOT --trajectories`: a shot's paths for the pedestrian-dynamics field's own tools.

PedPy (the JuPedSim team's analysis library, in its own venv) reads the
text file with no extra arguments and JuPedSim's SQLite file; JuPedSim's own
``Recording`` (in its own venv too) reads the database. Positions are checked against the hips'
joint as plain usd-core composes it (UsdSkel, no usdcrowd imported).
"""

from __future__ import annotations

import json
import subprocess
import textwrap

import numpy as np
import pytest

from usdcrowd.cli import main

from tests.helpers.plain_usd import people_as_plain_usd_sees_them
from tests.helpers import venvs
SAMPLES = (1, 2, 40, 119)          # time codes the positions are checked at


@pytest.fixture(scope="module")
def pedpy_python():
    return venvs.pedpy_python()


@pytest.fixture(scope="module")
def exported_harbour(simulated_harbour, tmp_path_factory):
    """The simulated harbour's frames 1-120 as PedPy text (every frame) and JuPedSim SQLite (every second)."""
    out = tmp_path_factory.mktemp("trajectories")
    shot = str(simulated_harbour / "shot.usda")
    assert main(["export", shot, "--trajectories", str(out / "harbour.txt"), "--frames", "1:120",
                 "--no-progress"]) == 0
    assert main(["export", shot, "--trajectories", str(out / "harbour.sqlite"), "--frames", "1:120x2",
                 "--no-progress"]) == 0
    return out


def _run(python: str, script: str) -> dict:
    out = subprocess.run([python, "-c", textwrap.dedent(script)], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


def _hips_as_plain_usd_sees_them(shot) -> dict:
    """{agent id: [[visible, x, y] per SAMPLES time code]}: the hips' joint in the world, by UsdSkel."""
    people = people_as_plain_usd_sees_them(shot, SAMPLES)["people"]
    return {i: [[bool(r[0]), r[1], r[2]] for r in p["rows"]] for i, p in people.items()}


def _as_pedpy_reads_them(python: str, folder) -> dict:
    return _run(python, f"""
        import json, pathlib
        import pedpy
        text = pedpy.load_trajectory(trajectory_file=pathlib.Path({str(folder / "harbour.txt")!r}))
        db = pathlib.Path({str(folder / "harbour.sqlite")!r})
        sql = pedpy.load_trajectory_from_jupedsim_sqlite(trajectory_file=db)
        area = pedpy.load_walkable_area_from_jupedsim_sqlite(trajectory_file=db)
        speed = pedpy.compute_individual_speed(traj_data=text, frame_step=5,
                                               speed_calculation=pedpy.SpeedCalculation.BORDER_EXCLUDE)
        rows = lambda t: t.data[["id", "frame", "x", "y"]].values.tolist()
        print(json.dumps({{"text_fps": text.frame_rate, "sql_fps": sql.frame_rate, "text": rows(text),
                          "sql": rows(sql), "area": area.polygon.area, "bounds": list(area.polygon.bounds),
                          "speed_max": float(speed.speed.max()), "speed_rows": len(speed)}}))
    """)


def _by_id_and_frame(rows) -> dict:
    return {(int(i), int(f)): (x, y) for i, f, x, y in rows}


def test_pedpy_reads_the_exported_paths_where_the_skeletons_stand(simulated_harbour, exported_harbour, pedpy_python):
    """Both files, read by PedPy with no extra arguments, hold every rendered person's hips (plain UsdSkel) at
    their frame, to a millimetre, at the frame rate of the export; nobody who is hidden has a row; PedPy's
    own speeds are a walker's."""
    hips = _hips_as_plain_usd_sees_them(simulated_harbour / "shot.usda")
    read = _as_pedpy_reads_them(pedpy_python, exported_harbour)
    assert read["text_fps"] == 24.0 and read["sql_fps"] == 12.0
    text, sql = _by_id_and_frame(read["text"]), _by_id_and_frame(read["sql"])
    checked = 0
    for agent, rows in hips.items():
        agent = int(agent)
        for t, (seen, x, y) in zip(SAMPLES, rows):
            for table, frame in ((text, t - 1), (sql, (t - 1) // 2 if (t - 1) % 2 == 0 else None)):
                if frame is None:
                    continue
                if not seen:
                    assert (agent, frame) not in table, (agent, t)
                    continue
                assert np.allclose(table[agent, frame], (x, y), atol=1e-3), (agent, t, table.get((agent, frame)))
                checked += 1
    assert checked > 100
    assert 0.3 < read["speed_max"] < 4.0 and read["speed_rows"] > 1000


def test_the_database_carries_the_walkable_area_jupedsim_reads(simulated_harbour, exported_harbour):
    """JuPedSim's own Recording (in its own venv) opens the database: its frame rate, frame count, people per
    frame and the walkable area (the scenario's bounds less the scenery's footprints) are those of the shot."""
    import shapely

    from usdcrowd.jobs.toric_filming import shot_obstacles
    from usdcrowd.scenario.shot_scene import ShotScene

    python = venvs.jupedsim_python()
    rec = _run(python, f"""
        import json
        import jupedsim
        rec = jupedsim.Recording({str(exported_harbour / "harbour.sqlite")!r})
        print(json.dumps({{"fps": rec.fps, "frames": rec.num_frames, "wkt": rec.geometry().wkt,
                          "positions": [list(a.position) for a in rec.frame(20).agents]}}))
    """)
    assert rec["fps"] == 12.0 and rec["frames"] == 60
    scene = ShotScene(simulated_harbour / "shot.usda")
    assert len(rec["positions"]) == scene.agents(41).visible.sum()
    area = shapely.from_wkt(rec["wkt"])
    obstacles = shot_obstacles(scene)
    assert len(obstacles) > 0
    for poly in obstacles.polygons:            # every footprint's centre is outside the walkable area
        assert not area.contains(shapely.Point(*poly.mean(axis=0))), poly.mean(axis=0)
    inside = [area.buffer(0.5).contains(shapely.Point(*p)) for p in rec["positions"]]
    assert np.mean(inside) > 0.99


def test_a_careless_trajectories_export_is_one_line_and_writes_nothing(simulated_harbour, tmp_path, capsys):
    """A wrong extension, and frames the shot does not have: one line naming the file, exit 2, no file."""
    shot = str(simulated_harbour / "shot.usda")
    for args, words in (([str(tmp_path / "t.csv")], "name it *.txt or *.sqlite"),
                        ([str(tmp_path / "t.txt"), "--frames", "5000:5010"], "shot.usda")):
        assert main(["export", shot, "--trajectories", *args, "--no-progress"]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and words in err, err
    assert not list(tmp_path.iterdir())
