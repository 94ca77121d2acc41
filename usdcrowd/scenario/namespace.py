"""Prim paths stored as values, seen from the stage that composes them.

Relationships are remapped by USD when a layer is referenced under another
path; a path kept in a string (a toric camera's time-sampled targets, which a
relationship cannot hold) is not. These functions map such a path through the
composition arc that supplied the value, so a shot referenced into a set at
``/Set/Shot/World`` names its agents there.
"""

from __future__ import annotations


def stage_path(attr, text: str, time=None) -> str:
    """``text``, a prim path authored in the layer that gave ``attr`` its value at ``time``, in the
    stage's namespace (unchanged when that layer is in the stage's own layer stack, or not a path)."""
    from pxr import Sdf, Usd

    if not text or not text.startswith("/") or not Sdf.Path.IsValidPathString(text):
        return text
    info = attr.GetResolveInfo(Usd.TimeCode.Default() if time is None else Usd.TimeCode(float(time)))
    node = info.GetNode()
    if not node or node.mapToRoot.isIdentity:
        return text
    mapped = node.mapToRoot.MapSourceToTarget(Sdf.Path(text))
    return str(mapped) if not mapped.isEmpty else text
