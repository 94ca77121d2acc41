"""Damaging a shot on purpose, for the tests of what every command does with it."""

from __future__ import annotations

from pathlib import Path


def spoil_root_translation(crowd_layer: Path, time: float, value: float):
    """Set the first agent's root joint x translation at ``time`` to ``value`` (NaN, inf); returns its path."""
    from pxr import Gf, Sdf, Vt

    crowd = Sdf.Layer.FindOrOpen(str(crowd_layer))
    paths = []
    crowd.Traverse("/", lambda p: paths.append(p) if p.IsPropertyPath() and p.name == "translations" else None)
    target = sorted(paths)[0]
    rest = list(crowd.QueryTimeSample(target, time))[1:]
    crowd.SetTimeSample(target, time, Vt.Vec3fArray([Gf.Vec3f(value, 0, 0)] + rest))
    crowd.Save()
    return target
