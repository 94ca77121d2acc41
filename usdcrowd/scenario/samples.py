"""Reading many time samples fast: from the layers that hold them, not one composed query per frame.

A composed ``attr.Get(t)`` costs microseconds of resolution per call, which
dominates when thousands of agents are read over hundreds of frames. The
samples usually sit unchanged in one layer (the crowd layer), or in
consecutive value-clip layers (:mod:`usdcrowd.usd.clips`), so they are taken
from there in runs: for each run, the strongest spec with time samples at its
first time, as far as that spec has every frame asked for.
"""

from __future__ import annotations


def authored_samples(attr, times: list[float]) -> list | None:
    """The values of ``attr`` at ``times``, read from the layers that author them.

    Each run of times is checked against the composed value at its first,
    middle and last time; where they differ (a layer offset, a clip's time
    mapping, a stronger default), or where a time has no authored sample,
    the answer is None and the caller composes per frame.

    Parameters
    ----------
    attr : Usd.Attribute
    times : list of float
        Time codes, increasing.

    Returns
    -------
    list or None
        One value per time (Vt arrays or scalars, as USD holds them).
    """
    from pxr import Usd

    values: list = []
    query = Usd.AttributeQuery(attr)
    i, n = 0, len(times)
    while i < n:
        found = None
        for spec in attr.GetPropertyStack(Usd.TimeCode(times[i])):
            if spec.layer.GetNumTimeSamplesForPath(spec.path):
                found = spec.GetInfo("timeSamples")
                break
        if found is None or times[i] not in found:
            return None
        j = i
        while j < n and times[j] in found:
            j += 1
        run = [found[t] for t in times[i:j]]
        if any(query.Get(times[i + k]) != run[k] for k in {0, (j - i) // 2, j - i - 1}):
            return None
        values += run
        i = j
    return values


def sample_values(attr, times: list[float]) -> list:
    """The values of ``attr`` at ``times``: :func:`authored_samples`, else composed a frame at a time."""
    from pxr import Usd

    values = authored_samples(attr, times)
    if values is None:
        query = Usd.AttributeQuery(attr)
        values = [query.Get(t) for t in times]
    return values
