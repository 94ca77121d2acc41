"""A shot's walking paths for pedestrian-dynamics tools: PedPy's text format and JuPedSim's SQLite.

Both hold, per frame, each person's position on the ground (metres, the
shot's Z-up world); a person who is not rendered at a frame (not yet
spawned, gone, an invisible group leader) has no row there.

Text (``.txt``), the Pedestrian Dynamics Data Archive's layout that
``pedpy.load_trajectory`` reads: ``ID FR X Y Z`` separated by white space,
``#`` comment lines first. Its header carries the frame rate (a line with
``framerate``) and the unit (``x/m`` in the column line), so PedPy needs no
extra arguments. Z is the top of the head (world Z), as the Jülich
experiments' markers on the head give it: on flat ground, the body's height.

SQLite (``.sqlite``), JuPedSim's trajectory database (version 2, what
``jupedsim.SqliteTrajectoryWriter`` writes and ``jupedsim.Recording`` and
``pedpy.load_trajectory_from_jupedsim_sqlite`` read): ``trajectory_data``
(frame, id, pos_x, pos_y, ori_x, ori_y), ``metadata`` (version, fps and the
area's bounds), ``geometry`` (the walkable area as WKT: the scenario's
bounds less its scenery's footprints) and ``frame_data``.

Frames are numbered from 0 at the first exported time code; the frame rate
is the shot's divided by the export's time-code step (``--frames 1:900x2``
at 24 fps: 12 frames per second).
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

FORMATS = (".txt", ".sqlite")
JUPEDSIM_DATABASE_VERSION = 2


@dataclass
class Trajectories:
    """Where every person stands, frame by frame.

    Attributes
    ----------
    ids : (n,) int
        Track ids (``crowd:agentId``, the ids of the MOT ground truth).
    times : (k,) float
        Time codes exported.
    fps : float
        Frames per second of the export.
    xy : (k, n, 2) float
        Ground positions, metres; NaN where a person is not in the frame.
    facing : (k, n, 2) float
        Unit facing direction on the ground.
    head : (k, n) float
        Top of the head (world Z), metres.
    walkable_wkt : str or None
        The walkable area as WKT (the scenario's bounds less its scenery).
    """

    ids: np.ndarray
    times: np.ndarray
    fps: float
    xy: np.ndarray
    facing: np.ndarray
    head: np.ndarray
    walkable_wkt: str | None = None

    def rows(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The present (frame, person) pairs, frame-major: (m,) frame numbers, (m,) ids, (m,) person columns."""
        frame, col = np.nonzero(np.isfinite(self.xy[..., 0]))
        return frame, self.ids[col], col


def read_trajectories(scene, times, progress: bool = False) -> Trajectories:
    """A shot's paths over ``times`` ((k,) time codes, evenly spaced), read from its skeletons.

    The ground position is the hips' joint dropped to the ground, the
    facing the hips' forward axis, the head the rig's head top
    (:func:`usdcrowd.character.rig.keypoints`).

    Raises
    ------
    UsdcrowdError
        Time codes that are not evenly spaced (no frame rate describes them).
    """
    from tqdm import tqdm

    from ..character.rig import KEYPOINT_NAMES, keypoints
    from ..core.errors import UsdcrowdError

    times = np.asarray(times, dtype=np.float64)
    step = np.diff(times)
    if len(step) and np.ptp(step) > 1e-6:
        raise UsdcrowdError("trajectories need evenly spaced frames (a frame rate): give --frames as START:END[xSTEP]",
                            file=scene.path)
    fps = float(scene.fps) / (float(step[0]) if len(step) else 1.0)
    n = len(scene.agent_paths)
    xy = np.full((len(times), n, 2), np.nan)
    facing = np.zeros((len(times), n, 2))
    head = np.zeros((len(times), n))
    ids = None
    for k, t in enumerate(tqdm(times, desc="trajectories", unit="frame", disable=not progress, leave=False)):
        poses = scene.agents(t)
        ids = poses.agent_ids
        hips = poses.joints_world[:, 0]
        forward = hips[:, 0, :2] / np.maximum(np.linalg.norm(hips[:, 0, :2], axis=1, keepdims=True), 1e-12)
        top = keypoints(poses.joints_world)[:, KEYPOINT_NAMES.index("headTop")]
        on = poses.visible
        xy[k, on] = hips[on, 3, :2]
        facing[k] = forward
        head[k] = top[:, 2]
    return Trajectories(np.asarray(ids if ids is not None else np.zeros(0), dtype=np.int64), times, fps, xy, facing,
                        head, walkable_area(scene))


def walkable_area(scene) -> str | None:
    """WKT of the walkable area of the scenario a shot names: its bounds less the scenery's footprints (None
    without a scenario)."""
    import shapely

    from ..scenario import shot_scenario

    scenario = shot_scenario(scene)
    if scenario is None:
        return None
    (x0, y0), (x1, y1) = np.asarray(scenario.bounds, dtype=np.float64)
    area = shapely.box(x0, y0, x1, y1)
    if len(scenario.obstacles):
        area = area.difference(shapely.union_all([shapely.Polygon(p) for p in scenario.obstacles.polygons]))
    return shapely.to_wkt(area, rounding_precision=6)


def write_trajectories(traj: Trajectories, final: str | os.PathLike, shot_name: str = "") -> int:
    """Write ``traj`` to ``final`` (.txt or .sqlite, by its extension), whole or not at all; the rows written."""
    from ..atomic import atomic_path

    suffix = os.path.splitext(os.fspath(final))[1].lower()
    with atomic_path(final) as tmp:
        if suffix == ".sqlite":
            return _write_sqlite(traj, tmp)
        return _write_text(traj, tmp, shot_name)


def _write_text(traj: Trajectories, path, shot_name: str) -> int:
    frame, ids, col = traj.rows()
    table = np.column_stack([ids, frame, traj.xy[frame, col], traj.head[frame, col]])
    first = traj.times[0] if len(traj.times) else 0.0
    step = traj.times[1] - traj.times[0] if len(traj.times) > 1 else 1.0
    # The column line comes last: PedPy takes the unit from the last header line naming one.
    header = [f"usdcrowd trajectories{': ' + shot_name if shot_name else ''}",
              f"framerate: {traj.fps:g} fps",
              f"frame 0 is time code {first:g}, one frame every {step:g} time code(s)",
              "Z: the top of the head (world Z)",
              "ID\tFR\tX/m\tY/m\tZ/m"]
    with open(path, "w", encoding="utf-8") as f:
        f.write("".join(f"# {line}\n" for line in header))
        np.savetxt(f, table, fmt=["%d", "%d", "%.4f", "%.4f", "%.4f"], delimiter="\t")
    return len(table)


def _write_sqlite(traj: Trajectories, path) -> int:
    import hashlib
    import sqlite3

    frame, ids, col = traj.rows()
    rows = zip(frame.tolist(), ids.tolist(), *(traj.xy[frame, col].T.tolist()), *(traj.facing[frame, col].T.tolist()))
    wkt = traj.walkable_wkt or _hull_wkt(traj)
    geometry_hash = int.from_bytes(hashlib.sha1(wkt.encode()).digest()[:7], "big")     # fits SQLite's int64
    bounds = _bounds(wkt)
    con = sqlite3.connect(os.fspath(path))
    try:
        with con:
            con.execute("CREATE TABLE trajectory_data (frame INTEGER NOT NULL, id INTEGER NOT NULL, "
                        "pos_x REAL NOT NULL, pos_y REAL NOT NULL, ori_x REAL NOT NULL, ori_y REAL NOT NULL)")
            con.execute("CREATE TABLE metadata(key TEXT NOT NULL UNIQUE PRIMARY KEY, value TEXT NOT NULL)")
            con.executemany("INSERT INTO metadata VALUES(?, ?)",
                            [("version", str(JUPEDSIM_DATABASE_VERSION)), ("fps", repr(float(traj.fps))),
                             *zip(("xmin", "ymin", "xmax", "ymax"), map(repr, bounds))])
            con.execute("CREATE TABLE geometry(hash INTEGER NOT NULL, wkt TEXT NOT NULL)")
            con.execute("CREATE UNIQUE INDEX geometry_hash on geometry(hash)")
            con.execute("INSERT INTO geometry VALUES(?, ?)", (geometry_hash, wkt))
            con.execute("CREATE TABLE frame_data(frame INTEGER NOT NULL, geometry_hash INTEGER NOT NULL)")
            con.executemany("INSERT INTO frame_data VALUES(?, ?)", [(k, geometry_hash) for k in range(len(traj.times))])
            con.executemany("INSERT INTO trajectory_data VALUES(?, ?, ?, ?, ?, ?)", rows)
            con.execute("CREATE INDEX frame_id_idx ON trajectory_data(frame, id)")
    finally:
        con.close()
    return len(frame)


def _hull_wkt(traj: Trajectories) -> str:
    """Without a scenario: the box round every position, a metre clear (JuPedSim's reader needs an area)."""
    import shapely

    pts = traj.xy[np.isfinite(traj.xy[..., 0])]
    if not len(pts):
        return "POLYGON EMPTY"
    (x0, y0), (x1, y1) = pts.min(axis=0) - 1.0, pts.max(axis=0) + 1.0
    return shapely.to_wkt(shapely.box(x0, y0, x1, y1), rounding_precision=6)


def _bounds(wkt: str) -> tuple[float, float, float, float]:
    import shapely

    geom = shapely.from_wkt(wkt)
    return tuple(float(v) for v in geom.bounds) if not geom.is_empty else (0.0, 0.0, 0.0, 0.0)
