"""CrowdEvent prims for detected events, authored into a generated layer.

``crowd:members`` lists everyone who ever took part; the time-sampled
``int[] crowd:memberIds`` (agent ids) says who takes part at each frame,
since relationships cannot vary in time. Membership samples are written
only where it changes (int arrays hold their value between samples);
``crowd:center`` and ``crowd:radius`` are sampled every frame.
"""

from __future__ import annotations

import numpy as np

from ..core import model
from ..scenario.stageio import StageFrame
from ..scenario.parent_space import points_in_parent, scale_of


def author_events(layer, events: model.EventTable, agent_paths: list[str], agent_ids: np.ndarray,
                  frame: StageFrame, parents=None) -> int:
    """Define a CrowdEvent prim in ``layer`` for every event not authored by the user.

    ``crowd:center`` and ``crowd:radius`` are in the space of the event's parent on the stage the
    events were found on (``parents``, a :class:`~usdcrowd.scenario.parent_space.ParentSpace`; default:
    the world), so they move with the shot. Call inside an ``Sdf.ChangeBlock``. Returns the number
    written.
    """
    from pxr import Gf, Sdf, Vt

    T = Sdf.ValueTypeNames
    ids = np.asarray(agent_ids)
    to_stage = frame.from_canonical[:3, :3]
    n = 0
    for e in events:
        if e.authored:
            continue
        parts = e.path.strip("/").split("/")
        for k in range(1, len(parts)):
            p = "/" + "/".join(parts[:k])
            if not layer.GetPrimAtPath(p):
                Sdf.CreatePrimInLayer(layer, p).specifier = Sdf.SpecifierDef
        spec = Sdf.CreatePrimInLayer(layer, e.path)
        spec.specifier, spec.typeName = Sdf.SpecifierDef, "CrowdEvent"
        _uniform(spec, "crowd:kind", T.Token, model.EVENT_KINDS[e.kind])
        Sdf.AttributeSpec(spec, "crowd:detected", T.Bool, Sdf.VariabilityUniform, True).default = True
        _uniform(spec, "crowd:startTime", T.Double, float(e.start))
        _uniform(spec, "crowd:endTime", T.Double, float(e.end))
        rel = Sdf.RelationshipSpec(spec, "crowd:members", custom=False)
        rel.targetPathList.explicitItems = [Sdf.Path(agent_paths[int(row)]) for row in e.members]
        member_ids = Sdf.AttributeSpec(spec, "crowd:memberIds", T.IntArray)
        prev = None
        for i, t in enumerate(e.times):
            cur = tuple(int(v) for v in ids[e.members[e.active[i]]])
            if cur != prev:
                layer.SetTimeSample(member_ids.path, float(t), Vt.IntArray(cur))
                prev = cur
        centre = Sdf.AttributeSpec(spec, "crowd:center", T.Point3f)
        radius = Sdf.AttributeSpec(spec, "crowd:radius", T.Float)
        c_stage = np.asarray(e.center, dtype=np.float64) @ to_stage
        r_stage = np.asarray(e.radius, dtype=np.float64) / frame.meters_per_unit
        if parents is not None:
            parent = parents.of(e.path, e.times)
            c_stage = points_in_parent(c_stage, parent)
            r_stage = r_stage / scale_of(parent)
        for t, c, r in zip(e.times, c_stage, r_stage):
            layer.SetTimeSample(centre.path, float(t), Gf.Vec3f(*map(float, c)))
            layer.SetTimeSample(radius.path, float(t), float(r))
        n += 1
    return n


def _uniform(spec, name, type_name, value):
    from pxr import Sdf

    a = Sdf.AttributeSpec(spec, name, type_name, Sdf.VariabilityUniform)
    a.default = value
    return a
