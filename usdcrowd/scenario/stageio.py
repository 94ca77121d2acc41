"""Opening stages with clear errors, and their axes and units.

Every stage that comes in is read in its own upAxis and metersPerUnit and
turned into usdcrowd's canonical frame (Z up, metres) with :class:`StageFrame`.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from .. import model
from ..errors import StageError, usd_error_text
from ..tolerances import UNIT_RTOL

# A stage without an authored time range is read as this one.
DEFAULT_TIME = model.TimeRange(1.0, 240.0, 24.0)

# Row-vector convention (USD's): p_canonical = p_stage @ matrix.
_Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


@dataclass(frozen=True)
class StageFrame:
    """A stage's up axis and unit, and the maps to and from the canonical frame."""

    up_axis: str = "Z"
    meters_per_unit: float = 1.0

    @property
    def is_canonical(self) -> bool:
        return self.up_axis == "Z" and abs(self.meters_per_unit - 1.0) <= UNIT_RTOL

    @property
    def to_canonical(self) -> np.ndarray:
        """(4, 4) float64: stage coordinates to canonical (row vectors)."""
        m = np.eye(4)
        rot = _Y_UP_TO_Z_UP if self.up_axis == "Y" else np.eye(3)
        m[:3, :3] = rot * self.meters_per_unit
        return m

    @property
    def from_canonical(self) -> np.ndarray:
        """(4, 4) float64: canonical coordinates to stage (row vectors)."""
        return np.linalg.inv(self.to_canonical)

    def points_to_canonical(self, p: np.ndarray) -> np.ndarray:
        """(..., 3) stage points to canonical metres."""
        return np.asarray(p, dtype=np.float64) @ self.to_canonical[:3, :3]

    def points_from_canonical(self, p: np.ndarray) -> np.ndarray:
        """(..., 3) canonical metres to stage points."""
        return np.asarray(p, dtype=np.float64) @ self.from_canonical[:3, :3]

    def length_to_canonical(self, d):
        return np.asarray(d, dtype=np.float64) * self.meters_per_unit


def stage_frame(stage) -> StageFrame:
    """Read upAxis and metersPerUnit of an open stage."""
    from pxr import UsdGeom

    return StageFrame(str(UsdGeom.GetStageUpAxis(stage)), float(UsdGeom.GetStageMetersPerUnit(stage)))


def time_range(stage) -> model.TimeRange:
    """The stage's frames and rate (:data:`DEFAULT_TIME` when it authors no time range)."""
    if not stage.HasAuthoredTimeCodeRange():
        return DEFAULT_TIME
    fps = stage.GetTimeCodesPerSecond() or DEFAULT_TIME.fps
    return model.TimeRange(float(stage.GetStartTimeCode()), float(stage.GetEndTimeCode()), float(fps))


def open_stage(path: str | os.PathLike):
    """Open a USD stage, turning every way it can fail into one-line errors.

    Raises
    ------
    StageError
        Missing file, not a USD file, or a file USD cannot parse.
    """
    from pxr import Tf, Usd

    path = os.fspath(path)
    if not os.path.exists(path):
        raise StageError("no such file", file=path)
    if os.path.isdir(path):
        raise StageError("is a folder, not a USD file", file=path)
    try:
        stage = Usd.Stage.Open(path)
    except Tf.ErrorException as exc:
        raise StageError(f"not a readable USD file: {usd_error_text(exc)}", file=path) from None
    if stage is None:
        raise StageError("not a readable USD file", file=path)
    return stage
