"""Reynolds' steering behaviours as vectorised building blocks.

Every function works on structure-of-arrays vectors ``(2, n)`` (x row, y
row), float32. "Desired velocity" behaviours (seek, arrive, flee, pursue,
evade, wander) return a velocity the agent would like to have; :func:`steer`
turns it into a force ``(v_desired - v) / tau``. Neighbour behaviours
(separation, cohesion, alignment) take gathered pair arrays ``(2, n, k)``
(see :mod:`usdcrowd.sim.collision` and :mod:`usdcrowd.sim.groups`, which call
them). Forces are accelerations, m/s^2 (unit mass).
"""

from __future__ import annotations

import numpy as np

from . import params as P

_EPS = np.float32(1e-6)


def unit(v: np.ndarray):
    """Unit vectors and norms of ``(2, n)`` vectors (zero stays zero)."""
    norm = np.sqrt(v[0] * v[0] + v[1] * v[1])
    return v / np.maximum(norm, _EPS), norm


def steer(v_desired: np.ndarray, v: np.ndarray, tau: float = P.TAU_RELAX) -> np.ndarray:
    """Steering force toward a desired velocity, (2, n) m/s^2."""
    return (v_desired - v) * np.float32(1.0 / tau)


def seek(pos: np.ndarray, target: np.ndarray, speed: np.ndarray) -> np.ndarray:
    """Full speed straight at ``target``.

    Parameters
    ----------
    pos, target : (2, n)
    speed : (n,) m/s

    Returns
    -------
    (2, n) desired velocity
    """
    u, _ = unit(target - pos)
    return u * speed


def arrive(pos: np.ndarray, target: np.ndarray, speed: np.ndarray,
           slow_radius: float | np.ndarray = P.SLOW_RADIUS, stop_radius: float | np.ndarray = 0.0):
    """Seek that slows down linearly inside ``slow_radius`` and stops at ``stop_radius``.

    Returns
    -------
    (2, n) desired velocity, (n,) distance to the target
    """
    u, d = unit(target - pos)
    ramp = np.minimum(np.maximum((d - stop_radius) / slow_radius, 0.0), 1.0)
    return u * (speed * ramp), d


def flee(pos: np.ndarray, threat: np.ndarray, speed: np.ndarray) -> np.ndarray:
    """Full speed directly away from ``threat``, (2, n)."""
    u, _ = unit(pos - threat)
    return u * speed


def predict(pos: np.ndarray, target_pos: np.ndarray, target_vel: np.ndarray, speed: np.ndarray,
            max_time: float = 3.0) -> np.ndarray:
    """Where a moving target will be when we could reach it (pursue / evade)."""
    _, d = unit(target_pos - pos)
    t = np.minimum(d / np.maximum(speed, _EPS), max_time)
    return target_pos + target_vel * t


def pursue(pos, vel_target, target_pos, speed):
    """Seek the predicted position of a moving target, (2, n)."""
    return seek(pos, predict(pos, target_pos, vel_target, speed), speed)


def evade(pos, vel_threat, threat_pos, speed):
    """Flee the predicted position of a moving threat, (2, n)."""
    return flee(pos, predict(pos, threat_pos, vel_threat, speed), speed)


def wander(heading: np.ndarray, angle: np.ndarray, noise: np.ndarray, dt: float, speed: np.ndarray):
    """Reynolds' wander: steer toward a jittered point on a circle ahead.

    Parameters
    ----------
    heading : (n,) yaw, rad
    angle : (n,) wander angle on the circle, rad (updated in place)
    noise : (n,) standard normal draws
    dt : float, s
    speed : (n,) m/s

    Returns
    -------
    (2, n) desired velocity
    """
    angle += noise * np.float32(P.WANDER_RATE * np.sqrt(dt))
    a = heading + angle
    tx = np.cos(heading) * P.WANDER_DISTANCE + np.cos(a) * P.WANDER_RADIUS
    ty = np.sin(heading) * P.WANDER_DISTANCE + np.sin(a) * P.WANDER_RADIUS
    u, _ = unit(np.stack([tx, ty]).astype(np.float32))
    return u * speed


def separation(dx: np.ndarray, dist: np.ndarray, gap: np.ndarray, personal: float = P.PERSONAL_GAP,
               gain: float = P.SEPARATION_GAIN) -> np.ndarray:
    """Short-range push away from neighbours closer than ``personal`` (gap).

    Parameters
    ----------
    dx : (2, n, k) own position minus neighbour's
    dist : (n, k) centre distance
    gap : (n, k) distance minus both radii

    Returns
    -------
    (2, n) force
    """
    w = np.clip((personal - gap) * np.float32(gain / personal), 0.0, None) / np.maximum(dist, _EPS)
    return np.einsum("cnk,nk->cn", dx, w)


def cohesion(dx: np.ndarray, mask: np.ndarray, count: np.ndarray, gain: float = P.COHESION_GAIN):
    """Attraction to the centre of the masked neighbours (seed 003, E_F).

    ``centre - x = -mean(dx)`` over the masked pairs.
    """
    s = np.einsum("cnk,nk->cn", dx, mask)
    return s * (-np.float32(gain) / np.maximum(count, 1.0))


def alignment(dv: np.ndarray, mask: np.ndarray, count: np.ndarray, gain: float = P.ALIGN_GAIN):
    """Velocity matching with the masked neighbours (seed 003, E_V).

    ``mean(v_j) - v = -mean(dv)`` over the masked pairs.
    """
    s = np.einsum("cnk,nk->cn", dv, mask)
    return s * (-np.float32(gain) / np.maximum(count, 1.0))


def containment(pos: np.ndarray, vel: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                lookahead: float = P.CONTAIN_LOOKAHEAD, gain: float = P.CONTAIN_GAIN) -> np.ndarray:
    """Steer back when the position predicted ``lookahead`` ahead leaves the bounds.

    Parameters
    ----------
    pos, vel : (2, n)
    lo, hi : (2,) bounds, metres

    Returns
    -------
    (2, n) force, proportional to the predicted overshoot
    """
    ahead = pos + vel * np.float32(lookahead)
    over = np.minimum(ahead - lo[:, None], 0.0) + np.maximum(ahead - hi[:, None], 0.0)
    return over * np.float32(-gain)


def clip_norm(v: np.ndarray, limit: np.ndarray) -> np.ndarray:
    """Scale ``(2, n)`` vectors down to at most ``limit`` (n,) in length, in place."""
    n2 = v[0] * v[0] + v[1] * v[1]
    s = np.where(n2 > limit * limit, limit / np.sqrt(np.maximum(n2, 1e-12)), 1.0).astype(v.dtype)
    v *= s
    return v
