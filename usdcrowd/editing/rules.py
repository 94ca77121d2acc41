"""Continuity rules between two consecutive shots of one event.

- **30 degrees:** two shots of the same subject from nearly the same
  direction look like a jump in time (a jump cut). The camera must move
  round the subject by at least ``min_angle_deg`` (seen from above, about
  the event's centre), unless the cut changes the shot's size clearly (a cut
  in or out along the axis, ``cut_in_ratio``).
- **180 degrees:** the subject's line of action (two people facing each
  other, a group's direction of travel) splits the ground in two sides;
  cutting to the other side flips left and right on screen. Both shots stay
  on one side; a camera on the line itself (within ``line_tolerance_deg``)
  belongs to both.
"""

from __future__ import annotations

import numpy as np

from .params import EditParams

OK = ""
JUMP_CUT = "30-degree rule"
LINE_CROSSED = "180-degree rule"


def angle_about(eye_a: np.ndarray, eye_b: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Degrees between the directions from ``centre`` to ``eye_a`` and to ``eye_b``, seen from above.

    Parameters
    ----------
    eye_a, eye_b : (..., 2 or 3) float
    centre : (..., 2 or 3) float
    """
    a = np.asarray(eye_a, dtype=np.float64)[..., :2] - np.asarray(centre, dtype=np.float64)[..., :2]
    b = np.asarray(eye_b, dtype=np.float64)[..., :2] - np.asarray(centre, dtype=np.float64)[..., :2]
    cross = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return np.degrees(np.abs(np.arctan2(cross, np.einsum("...i,...i->...", a, b))))


def side_of_line(eye: np.ndarray, centre: np.ndarray, line: np.ndarray, tolerance_deg: float) -> np.ndarray:
    """+1 or -1 for the side of the line of action a camera stands on; 0 on the line or where there is none.

    Parameters
    ----------
    eye, centre : (..., 2 or 3) float
    line : (..., 2) float
        Unit direction (zeros: no line).
    """
    d = np.asarray(eye, dtype=np.float64)[..., :2] - np.asarray(centre, dtype=np.float64)[..., :2]
    line = np.asarray(line, dtype=np.float64)
    cross = line[..., 0] * d[..., 1] - line[..., 1] * d[..., 0]
    n = np.linalg.norm(d, axis=-1) * np.linalg.norm(line, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        sin = np.where(n > 1e-9, cross / np.where(n > 1e-9, n, 1.0), 0.0)
    return np.where(np.abs(sin) > np.sin(np.radians(tolerance_deg)), np.sign(sin), 0.0)


def broken_rule(eye_a, eye_b, centre, line, size_a, size_b, params: EditParams) -> np.ndarray:
    """The rule a cut from a shot at ``eye_a`` to one at ``eye_b`` of the same event breaks ("" for none).

    Arguments broadcast against each other (eyes and centre (..., 3), line
    (..., 2), sizes (...)); the result is an array of str of their shape.
    """
    angle = angle_about(eye_a, eye_b, centre)
    size_a, size_b = np.asarray(size_a, dtype=np.float64), np.asarray(size_b, dtype=np.float64)
    both = (size_a > 0) & (size_b > 0)          # a size unseen is no cut in
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(both, np.maximum(size_a, size_b) / np.where(both, np.minimum(size_a, size_b), 1.0), 1.0)
    jump = (angle < params.min_angle_deg) & (ratio < params.cut_in_ratio)
    sa = side_of_line(eye_a, centre, line, params.line_tolerance_deg)
    sb = side_of_line(eye_b, centre, line, params.line_tolerance_deg)
    crossed = sa * sb < 0
    out = np.full(np.broadcast(jump, crossed).shape, OK, dtype=object)
    out[np.broadcast_to(crossed, out.shape)] = LINE_CROSSED
    out[np.broadcast_to(jump, out.shape)] = JUMP_CUT
    return out
