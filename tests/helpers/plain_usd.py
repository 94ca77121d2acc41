"""A shot's people as plain usd-core sees them (UsdSkel, in a fresh interpreter, no usdcrowd imported)."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import numpy as np

# argv: the stage, then the time codes as JSON (null: every one). Prints, per agent id, per time code,
# [shown, hips x, hips y, hips' forward x, y, head's forward x, y], and crowd:height.
_SCRIPT = """
    import json, sys
    from pxr import Usd, UsdGeom, UsdSkel
    stage = Usd.Stage.Open(sys.argv[1])
    codes = json.loads(sys.argv[2]) or list(range(int(stage.GetStartTimeCode()), int(stage.GetEndTimeCode()) + 1))
    cache = UsdSkel.Cache()
    out = {"fps": stage.GetTimeCodesPerSecond(), "first": stage.GetStartTimeCode(), "people": {}}
    for prim in stage.Traverse():
        if not prim.IsA(UsdSkel.Root) or not prim.HasAttribute("crowd:agentId"):
            continue
        cache.Populate(UsdSkel.Root(prim), Usd.PrimDefaultPredicate)
        skel = UsdSkel.Skeleton(prim.GetChild("Skel"))
        query = cache.GetSkelQuery(skel)
        joints = list(skel.GetJointsAttr().Get())
        hips, head = joints.index("legs"), joints.index("legs/torso/head")
        rows = []
        for t in codes:
            m = query.ComputeJointWorldTransforms(UsdGeom.XformCache(t))
            shown = UsdGeom.Imageable(prim).ComputeVisibility(t) != UsdGeom.Tokens.invisible
            rows.append([shown, m[hips][3][0], m[hips][3][1], m[hips][0][0], m[hips][0][1],
                         m[head][0][0], m[head][0][1]])
        out["people"][int(prim.GetAttribute("crowd:agentId").Get())] = {
            "rows": rows, "height": prim.GetAttribute("crowd:height").Get()}
    print(json.dumps(out))
"""


def people_as_plain_usd_sees_them(stage, codes=None) -> dict:
    """``{"fps", "first", "people": {id: {"rows": (t, 7) float, "height": float}}}`` of ``stage`` at the
    time codes ``codes`` (default: every one); rows as in _SCRIPT."""
    out = subprocess.run([sys.executable, "-c", textwrap.dedent(_SCRIPT), str(stage),
                          json.dumps(None if codes is None else [float(c) for c in codes])],
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-3000:]
    read = json.loads(out.stdout.strip().splitlines()[-1])
    read["people"] = {int(k): {"rows": np.array(v["rows"], dtype=np.float64), "height": v["height"]}
                      for k, v in read["people"].items()}
    return read
