"""Trajectory files read in: recorded walkers and peers' simulations, for ``usdcrowd replay``.

Three layouts, told apart by extension and header (or named with ``fmt``):

- **JuPedSim's SQLite** (``.sqlite``, ``.db``): ``trajectory_data`` rows
  ``(frame, id, pos_x, pos_y, ...)`` and the frame rate in ``metadata``
  (key ``fps``); what ``jupedsim.SqliteTrajectoryWriter`` writes.
- **PedPy's text** (the Pedestrian Dynamics Data Archive's ``ID FR X Y Z``):
  white-space columns after ``#`` comment lines; a comment line holding
  ``framerate`` gives the rate (its first number), one holding ``x/cm`` or
  ``in cm`` says centimetres (metres otherwise). What ``usdcrowd export
  --trajectories`` and the Jülich experiments' files hold; Z, where given, is
  the head's height.
- **ETH/UCY** (``frame id x y``, tabs or spaces, world metres): the walking
  pedestrians of the ETH and UCY sets as the trajectory-forecasting
  literature ships them. Their frame numbers count video frames (25 per
  second for UCY, 15 for ETH) with a person annotated every 0.4 s; the file
  does not say so, so the rate is taken from ``fps`` or, failing that, from
  the commonest frame step over 0.4 s.

Every problem is one line naming the file (and the row or table).
"""

from __future__ import annotations

import os
import sqlite3
from dataclasses import dataclass

import numpy as np

from ..core.errors import UsdcrowdError
from ..scenario.ranges import MAX_EXTENT

FORMATS = ("jupedsim", "pedpy", "ethucy")
# ETH/UCY annotate a person every 0.4 s (2.5 Hz) whatever the video's rate.
ETHUCY_ANNOTATION_STEP_S = 0.4


@dataclass
class Tracks:
    """Rows of a trajectory file: where each person stands at the frames they were seen.

    Attributes
    ----------
    ids : (n,) int64
        Person ids, ascending.
    fps : float
        Frames per second the file's frame numbers count.
    frame : (m,) float64
        Frame number of each row.
    person : (m,) int64
        Row -> index into ``ids``.
    xy : (m, 2) float64
        Ground position, metres.
    head : (m,) float64
        Head height, metres; NaN where the file gives none.
    fmt : str
        One of FORMATS.
    source : str
        The file read.
    facing : (m,) float64 or None
        The way the person faces, radians (JuPedSim's orientation); NaN where
        the file gives none.
    """

    ids: np.ndarray
    fps: float
    frame: np.ndarray
    person: np.ndarray
    xy: np.ndarray
    head: np.ndarray
    fmt: str
    source: str
    facing: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.ids)

    @property
    def seconds(self) -> np.ndarray:
        """(m,) seconds of each row after the file's first frame."""
        return (self.frame - self.frame.min()) / self.fps

    @property
    def row_bounds(self) -> np.ndarray:
        """(n + 1,) int: person ``i``'s rows are ``row_bounds[i]:row_bounds[i + 1]`` (rows run person by person)."""
        return np.searchsorted(self.person, np.arange(len(self) + 1))


def guess_format(path: str) -> str:
    """The layout of ``path``: by extension, then by its first line."""
    ext = os.path.splitext(path)[1].lower()
    if ext in (".sqlite", ".db", ".sqlite3"):
        return "jupedsim"
    with open(path, encoding="utf-8-sig", errors="replace") as f:
        for line in f:
            if line.strip():
                break
        else:
            raise UsdcrowdError("the trajectory file is empty", file=path)
    if line.lstrip().startswith("#"):
        return "pedpy"
    return "pedpy" if len(line.split()) >= 5 else "ethucy"


def read_tracks(path: str | os.PathLike, fmt: str | None = None, fps: float | None = None) -> Tracks:
    """Read a trajectory file.

    Parameters
    ----------
    path : path-like
    fmt : str, optional
        One of FORMATS; default: :func:`guess_format`.
    fps : float, optional
        Frames per second of the file's frame numbers, where the file does
        not say (ETH/UCY, a PedPy file without a ``framerate`` line); a file
        that says another rate is refused.

    Raises
    ------
    UsdcrowdError
        Missing or unreadable file, unknown layout, bad rows, no frame rate.
    """
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise UsdcrowdError("no such trajectory file", file=path)
    fmt = fmt or guess_format(path)
    if fmt not in FORMATS:
        raise UsdcrowdError(f"unknown trajectory format {fmt!r}; choose one of: {', '.join(FORMATS)}", file=path)
    if fmt == "jupedsim":
        frame, ids, xy, head, said, facing = _read_jupedsim(path)
    elif fmt == "pedpy":
        frame, ids, xy, head, said = _read_pedpy(path)
        facing = np.full(len(frame), np.nan)
    else:
        frame, ids, xy, head, said = _read_ethucy(path)
        facing = np.full(len(frame), np.nan)
    frame, ids, xy, head, facing = _sorted_rows(path, frame, ids, xy, head, facing)
    rate = _frame_rate(path, fmt, frame, ids, said, fps)
    unique, person = np.unique(ids, return_inverse=True)
    return Tracks(unique, rate, frame, person.astype(np.int64), xy, head, fmt, path, facing)


def _read_jupedsim(path: str):
    try:
        with sqlite3.connect(f"file:{path}?mode=ro", uri=True) as con:
            columns = {c[1] for c in con.execute("PRAGMA table_info(trajectory_data)")}
            oriented = {"ori_x", "ori_y"} <= columns
            rows = _database_numbers(path, con.execute("SELECT frame, id, pos_x, pos_y"
                                                       + (", ori_x, ori_y" if oriented else "")
                                                       + " FROM trajectory_data").fetchall(), 6 if oriented else 4)
            meta = con.execute("SELECT value FROM metadata WHERE key = 'fps'").fetchone()
    except sqlite3.DatabaseError as exc:
        raise UsdcrowdError(f"not a JuPedSim trajectory database ({exc}): it needs the tables trajectory_data "
                            "(frame, id, pos_x, pos_y) and metadata (key, value)", file=path) from None
    said = None
    if meta is not None:
        try:
            said = float(meta[0])
        except (TypeError, ValueError):
            raise UsdcrowdError(f"metadata fps is {meta[0]!r}, not a number", file=path) from None
    facing = np.arctan2(rows[:, 5], rows[:, 4]) if rows.shape[1] == 6 else np.full(len(rows), np.nan)
    if rows.shape[1] == 6:
        facing[np.hypot(rows[:, 4], rows[:, 5]) < 1e-9] = np.nan
    return rows[:, 0], rows[:, 1], rows[:, 2:4], np.full(len(rows), np.nan), said, facing


def _database_numbers(path: str, fetched: list, columns: int) -> np.ndarray:
    """(m, columns) float the rows of trajectory_data; a value that is no number is one line naming its row."""
    try:
        return np.array(fetched, dtype=np.float64).reshape(-1, columns)
    except (TypeError, ValueError):
        for k, row in enumerate(fetched, start=1):
            try:
                np.array(row, dtype=np.float64)
            except (TypeError, ValueError):
                raise UsdcrowdError(f"trajectory_data row {k} is {tuple(row)!r}: expected numbers (frame, id, "
                                    "pos_x, pos_y, ori_x, ori_y)", file=path) from None
        raise


def _header(path: str) -> tuple[list[str], int]:
    """The leading ``#`` lines and how many lines they take."""
    lines = []
    with open(path, encoding="utf-8-sig", errors="replace") as f:
        for line in f:
            if not line.lstrip().startswith("#"):
                break
            lines.append(line)
    return lines, len(lines)


def _numbers(path: str, skip: int, layout: str, needed: int = 4, wanted: int = 4) -> np.ndarray:
    """(m, wanted) the numeric rows after ``skip`` header lines, NaN where a row stops after ``needed``
    columns; a bad row is one line naming it."""
    rows = []
    with open(path, encoding="utf-8-sig", errors="replace") as f:
        for number, line in enumerate(f, start=1):
            if number <= skip or not line.strip() or line.lstrip().startswith("#"):
                continue
            parts = line.replace(",", " ").split()[:wanted]
            try:
                values = [float(p) for p in parts]
            except ValueError:
                values = []
            if len(values) < needed or not np.isfinite(values).all():
                raise UsdcrowdError(f"line {number} is {line.strip()[:60]!r}: expected {layout}", file=path)
            rows.append(values + [np.nan] * (wanted - len(values)))
    if not rows:
        raise UsdcrowdError(f"no rows: expected {layout}", file=path)
    return np.array(rows, dtype=np.float64)


def _read_pedpy(path: str):
    header, skip = _header(path)
    said, scale = None, 1.0
    for line in header:
        low = line.lower()
        if "framerate" in low and said is None:
            for word in line.replace(":", " ").split():
                try:
                    said = float(word)
                    break
                except ValueError:
                    continue
        if "x/cm" in low or "in cm" in low:
            scale = 0.01
    rows = _numbers(path, skip, "ID FR X Y [Z] (PedPy's text)", wanted=5)
    return rows[:, 1], rows[:, 0], rows[:, 2:4] * scale, rows[:, 4] * scale, said


def _read_ethucy(path: str):
    rows = _numbers(path, 0, "frame id x y (ETH/UCY)")
    return rows[:, 0], rows[:, 1], rows[:, 2:4], np.full(len(rows), np.nan), None


def _frame_rate(path: str, fmt: str, frame: np.ndarray, ids: np.ndarray, said: float | None,
                fps: float | None) -> float:
    """The rate the file's frame numbers count: the file's word, else ``fps``, else (ETH/UCY) the step."""
    if said is not None and fps is not None and not np.isclose(said, fps):
        raise UsdcrowdError(f"the file says {said:g} frames per second, --fps says {fps:g}: leave --fps out",
                            file=path)
    rate = said if said is not None else fps
    if rate is None and fmt == "ethucy":
        steps = np.diff(frame)[(ids[1:] == ids[:-1])]          # rows run person by person, frame by frame
        steps = steps[steps > 0]
        if len(steps) == 0:
            raise UsdcrowdError("every person is seen at one frame only: give --fps", file=path)
        values, counts = np.unique(steps, return_counts=True)
        rate = float(values[np.argmax(counts)]) / ETHUCY_ANNOTATION_STEP_S
    if rate is None:
        raise UsdcrowdError("the file does not say its frame rate (no 'framerate' comment line): give --fps",
                            file=path)
    if not np.isfinite(rate) or rate <= 0:
        raise UsdcrowdError(f"frame rate {rate:g} is not a positive number", file=path)
    return float(rate)


def _sorted_rows(path, frame, ids, xy, head, facing):
    """The rows sorted by person then frame, whole-number ids; refused unless finite and one per
    (person, frame)."""
    if len(frame) == 0:
        raise UsdcrowdError("no trajectory rows", file=path)
    if not (np.isfinite(frame).all() and np.isfinite(xy).all()):
        raise UsdcrowdError("a frame number or a position is not a finite number", file=path)
    far = np.abs(xy).max(axis=1) > MAX_EXTENT
    if far.any():
        k = int(np.flatnonzero(far)[0])
        raise UsdcrowdError(f"person {ids[k]:g} at frame {frame[k]:g} stands at ({xy[k, 0]:g}, {xy[k, 1]:g}) m: "
                            f"usdcrowd's scenes lie within {MAX_EXTENT / 1000:g} km of the origin", file=path)
    whole = np.abs(ids - np.round(ids)) <= 1e-6
    if not whole.all():
        bad = ids[~whole][0]
        raise UsdcrowdError(f"person id {bad:g} is not a whole number", file=path)
    ids = np.round(ids).astype(np.int64)
    order = np.lexsort((frame, ids))
    frame, ids, xy, head, facing = frame[order], ids[order], xy[order], head[order], facing[order]
    same = (ids[1:] == ids[:-1]) & (np.abs(frame[1:] - frame[:-1]) <= 1e-6)
    if same.any():
        k = int(np.flatnonzero(same)[0])
        raise UsdcrowdError(f"person {ids[k]} has two rows at frame {frame[k]:g}", file=path)
    return frame, ids, xy, head, facing
