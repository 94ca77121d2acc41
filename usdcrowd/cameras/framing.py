"""The framing force's target: the range of viewpoints around an event (seed 000, section 4.3).

A group is framed by framing its left-most and right-most characters A and
B as seen from the camera. Every point that sees A and B under a constant
angle alpha lies on one of two circles through A and B (the inscribed-angle
theorem; Lino and Christie 2012): radius ``|AB| / (2 sin alpha)``, centres on
AB's bisector at ``|AB| / (2 tan alpha)`` from its midpoint. Points of those
arcs close to A or B give uninformative shots of one character, so where the
angle at a circle's centre between the point and the other centre is below
beta, the range follows a quadratic Bezier curve instead (Figure 7): P0 and
P2 on the two circles at angle beta, P1 where their tangents meet. The range
is a closed curve around the event; the camera is pulled to its nearest
point.

Everything is seen from above (x, y); height is the crane's business.
"""

from __future__ import annotations

import numpy as np

ARC_SAMPLES = 40
BEZIER_SAMPLES = 10


def extreme_pair(camera_xy: np.ndarray, points_xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The left-most and right-most of ``points_xy`` (k, 2) seen from ``camera_xy`` (2,)."""
    d = points_xy - camera_xy
    c = d.mean(axis=0)
    ang = np.arctan2(c[0] * d[:, 1] - c[1] * d[:, 0], d @ c)
    return points_xy[np.argmax(ang)], points_xy[np.argmin(ang)]


def viewpoint_range(a: np.ndarray, b: np.ndarray, camera_xy: np.ndarray, alpha, beta,
                    min_width=0.6) -> np.ndarray:
    """Closed polyline of viewpoints that frame A and B under ``alpha``.

    Parameters
    ----------
    a, b : (c, 2) float
        The two framed points per camera, metres.
    camera_xy : (c, 2) float
        Camera positions (used only when A and B nearly coincide, to widen
        them across the line of sight).
    alpha, beta : (c,) float
        Viewing angle and the Bezier cut-off, radians; beta > alpha.
    min_width : float or (c,) float
        AB is widened to at least this (one character is framed as a body
        width, not a point; an event as its area).

    Returns
    -------
    (c, s, 2) float64
        The range's vertices in order; the last joins the first.
    """
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    m = 0.5 * (a + b)
    ab = b - a
    length = np.linalg.norm(ab, axis=1)
    # Degenerate pairs: widen across the camera's line of sight.
    sight = m - camera_xy
    sight /= np.maximum(np.linalg.norm(sight, axis=1, keepdims=True), 1e-9)
    across = np.stack([-sight[:, 1], sight[:, 0]], 1)
    t = np.where(length[:, None] > 1e-6, ab / np.maximum(length, 1e-12)[:, None], across)
    length = np.maximum(length, min_width)
    n = np.stack([-t[:, 1], t[:, 0]], 1)
    alpha = np.asarray(alpha, dtype=np.float64)
    beta = np.clip(np.maximum(np.asarray(beta, dtype=np.float64), alpha + 1e-3), None, np.pi - 1e-3)
    r = length / (2.0 * np.sin(alpha))
    d = length / (2.0 * np.tan(alpha))

    def arc(sign, th):
        # sign +1: the circle on n's side; theta measured from the other centre's direction.
        centre = m + sign * d[:, None] * n
        return centre[:, None] + r[:, None, None] * (
            np.cos(th)[..., None] * (-sign * n)[:, None] + np.sin(th)[..., None] * t[:, None])

    u = np.linspace(0.0, 1.0, ARC_SAMPLES)[None]
    th = beta[:, None] + u * (2 * np.pi - 2 * beta[:, None])        # from near B round to near A
    arc1 = arc(+1, th)
    arc2 = arc(-1, th[:, ::-1])                                     # near A round to near B
    # Tangents at the cut points meet on AB's line, beyond A and B.
    s = r * np.sin(beta) + (r * np.cos(beta) - d) * np.cos(beta) / np.sin(beta)
    c_b = m + s[:, None] * t
    c_a = m - s[:, None] * t
    w = np.linspace(0.0, 1.0, BEZIER_SAMPLES + 2)[1:-1][None, :, None]

    def bezier(p0, p1, p2):
        return (1 - w) ** 2 * p0[:, None] + 2 * (1 - w) * w * p1[:, None] + w ** 2 * p2[:, None]

    near_a = bezier(arc1[:, -1], c_a, arc2[:, 0])
    near_b = bezier(arc2[:, -1], c_b, arc1[:, 0])
    return np.concatenate([arc1, near_a, arc2, near_b], axis=1)


def closest_on_polyline(poly: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Nearest points of closed polylines ``poly`` (c, s, 2) to ``p`` (c, 2), (c, 2)."""
    p0 = poly
    p1 = np.roll(poly, -1, axis=1)
    seg = p1 - p0
    w = p[:, None] - p0
    tt = np.clip(np.einsum("csk,csk->cs", w, seg) / np.maximum(np.einsum("csk,csk->cs", seg, seg), 1e-12), 0, 1)
    q = p0 + tt[..., None] * seg
    k = np.argmin(np.einsum("csk,csk->cs", q - p[:, None], q - p[:, None]), axis=1)
    return q[np.arange(len(p)), k]


def subtended_angle(camera_xy: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(c,) angle in radians under which a camera sees A and B (from above)."""
    u = a - camera_xy
    v = b - camera_xy
    return np.arctan2(np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]), np.einsum("ij,ij->i", u, v))
