"""An agent's static prims in a crowd layer: the SkelRoot with its resolved
attributes, its Skeleton, SkelAnimation (rotations and translations left for
the samples) and Body.

Some thirty-five specs an agent, authored one by one through the Sdf API,
cost about 0.27 ms an agent, a second and a half of a part writer's 5,000.
Agents whose prims have the same shape (the same optional properties, the
same specifier and placement) are therefore copied from the first such agent
of the layer (``Sdf.CopySpec``: one call, in C++, which also points the
copy's skeleton and animation bindings at its own children) and given their
own values where those differ: the layer holds the same specs and values as
if each had been written in full (``tests/usd/test_agent_prims.py``).
"""

from __future__ import annotations

import numpy as np

from ..core import model
from ..character import rig
from ..scenario.parent_space import in_parent, is_identity, parent_key
from ..schema import USER_PROPERTIES
from .specs import new_attribute, new_prim, set_palette, value_types

# Per-agent values: (child prim, property) -> how it is made from the agent's row. The SkelRoot's first.
_ROOT, _ANIM, _BODY = "", "Anim", "Body"
_TOKENS = (("crowd:role", "role", model.ROLES), ("crowd:characterType", "character_type", model.CHARACTER_TYPES),
           ("crowd:personality", "personality", model.PERSONALITIES), ("crowd:behavior", "behavior", model.BEHAVIORS),
           ("crowd:condition", "condition", model.CONDITIONS),
           ("crowd:fearResponse", "fear_response", model.FEAR_RESPONSES))
_STATE = ("crowd:state:behavior", "crowd:state:animClass", "crowd:state:health")
_INVISIBLE = model.ROLES.index("invisibleLeader")


class AgentPrims:
    """Writes agents' static prims into one layer, copying those of the same shape.

    Parameters
    ----------
    layer : Sdf.Layer
    scenario : Scenario
    frame : StageFrame
        The stage's axes and units.
    authored : set of str
        Agents the scenario defines itself: their SkelRoot is an ``over``.
    parents : dict
        Transforms of the agents' parents (:mod:`usdcrowd.scenario.parent_space`).
    prototypes : (str, str, str)
        The shared skeleton's, body's and materials' paths (crowd_layer.shared_paths).
    palette : (n, r, 3) float
        Every agent's body colours.
    starts : dict
        Agent row -> its start position in the stage's axes and units, (3,) list.
    copy : bool
        Copy agents of a shape already written (False: every agent spec by spec, the reference).
    """

    def __init__(self, layer, scenario: model.Scenario, frame, authored: set[str], parents: dict, prototypes,
                 palette, starts: dict, copy: bool = True):
        from pxr import Sdf, Vt

        self.copy = copy
        self.layer, self.scenario, self.frame = layer, scenario, frame
        self.authored, self.parents, self.palette, self.starts = authored, parents, palette, starts
        self._placements: dict = {}
        self._templates: dict = {}      # shape -> (its first agent's path, that agent's values)
        self._api = Sdf.TokenListOp.Create(prependedItems=["CrowdAgentAPI", "SkelBindingAPI"])
        self._joints = Vt.TokenArray(list(rig.JOINTS))
        self._skeleton = [Sdf.Reference(primPath=prototypes[0])]
        self._body = [Sdf.Reference(primPath=prototypes[1])]

    # -- what differs from agent to agent -----------------------------------------------------------
    def _shape(self, i: int) -> tuple:
        """What decides which specs an agent has (agents alike in it differ in values only)."""
        a = self.scenario.agents
        path = a.path[i]
        return (path in self.authored, a.leader[i] >= 0, bool(a.trades is not None and a.trades[i]),
                int(a.role[i]) == _INVISIBLE, parent_key(path))

    def _values(self, i: int, s: float) -> dict:
        """Agent ``i``'s own values, keyed by (child prim, property), as Python values (``s``: the root
        joint's scale)."""
        a, groups = self.scenario.agents, self.scenario.groups
        v = {(_ROOT, "crowd:agentId"): int(a.agent_id[i])}
        for name, field, vocab in _TOKENS:
            v[(_ROOT, name)] = vocab[getattr(a, field)[i]]
        v[(_ROOT, "crowd:maxSlope")] = float(a.max_slope[i])
        v[(_ROOT, "crowd:behaviorMapInfluence")] = float(a.map_influence[i])
        v[(_ROOT, "crowd:color")] = tuple(a.color[i].tolist())
        group = groups.path[a.group[i]]
        for name, value in (("agentId", int(a.agent_id[i])), ("group", group), ("role", model.ROLES[a.role[i]]),
                            ("characterType", model.CHARACTER_TYPES[a.character_type[i]])):
            v[(_ROOT, f"{USER_PROPERTIES}{name}")] = value
        v[(_ROOT, "crowd:speed")] = float(a.speed[i])
        v[(_ROOT, "crowd:height")] = float(a.height[i])
        v[(_ROOT, "crowd:startPosition")] = tuple(self.starts[i])
        v[(_ROOT, "crowd:group")] = group
        if a.leader[i] >= 0:
            v[(_ROOT, "crowd:leader")] = a.path[a.leader[i]]
        v[(_ANIM, "scales")] = s
        v[(_BODY, "primvars:crowd:height")] = float(a.height[i])
        return v

    # -- writing --------------------------------------------------------------------------------------
    def write(self, i: int, s: float):
        """Agent ``i``'s prims (``s``: its root joint's scale).

        Returns
        -------
        root : Sdf.PrimSpec
            Its SkelRoot.
        samples : tuple of Sdf.Path
            Its rotations, translations and the three state tokens, where the samples go.
        """
        path = self.scenario.agents.path[i]
        values = self._values(i, s)
        shape = self._shape(i)
        template = self._templates.get(shape)
        if template is None or not self.copy:
            root = self._write_full(i, path, values)
            self._templates[shape] = (path, values)
        else:
            root = self._copy(i, path, values, *template)
        at = root.path
        anim = at.AppendChild("Anim")
        return root, (anim.AppendProperty("rotations"), anim.AppendProperty("translations"),
                      *(at.AppendProperty(name) for name in _STATE))

    def _copy(self, i: int, path: str, values: dict, source: str, source_values: dict):
        from pxr import Gf, Sdf, Vt

        layer = self.layer
        root = Sdf.CreatePrimInLayer(layer, path)   # and its ancestors, as a full write makes them
        Sdf.CopySpec(layer, source, layer, path)
        at = root.path
        for (child, name), value in values.items():
            if source_values[(child, name)] == value:
                continue
            prop = (at.AppendChild(child) if child else at).AppendProperty(name)
            if name in ("crowd:group", "crowd:leader"):
                layer.GetRelationshipAtPath(prop).targetPathList.explicitItems = [value]
                continue
            if name == "scales":
                value = Vt.Vec3hArray([Gf.Vec3h(value, value, value), Gf.Vec3h(1, 1, 1), Gf.Vec3h(1, 1, 1)])
            elif isinstance(value, tuple):
                value = Gf.Vec3f(*value)
            layer.GetAttributeAtPath(prop).default = value
        layer.GetAttributeAtPath(at.AppendChild("Body").AppendProperty("primvars:displayColor")).default = \
            Vt.Vec3fArray.FromNumpy(np.asarray(self.palette[i], dtype=np.float32))
        return root

    def _write_full(self, i: int, path: str, v: dict):
        """Every spec of agent ``i`` one by one (the first of its shape)."""
        from pxr import Gf, Sdf, Vt

        T, U = value_types(), Sdf.VariabilityUniform
        layer, a = self.layer, self.scenario.agents
        spec = new_prim(layer, path, "SkelRoot", Sdf.SpecifierOver if path in self.authored else Sdf.SpecifierDef)
        spec.SetInfo("apiSchemas", self._api)
        new_attribute(spec, "crowd:agentId", T.Int, v[(_ROOT, "crowd:agentId")], U)
        for name, _, _ in _TOKENS:
            new_attribute(spec, name, T.Token, v[(_ROOT, name)], U)
        new_attribute(spec, "crowd:maxSlope", T.Float, v[(_ROOT, "crowd:maxSlope")], U)
        new_attribute(spec, "crowd:behaviorMapInfluence", T.Float, v[(_ROOT, "crowd:behaviorMapInfluence")], U)
        if a.trades is not None and a.trades[i]:
            new_attribute(spec, "crowd:trades", T.Bool, True, U)
        new_attribute(spec, "crowd:color", T.Color3f, Gf.Vec3f(*v[(_ROOT, "crowd:color")]), U)
        # The same facts again where DCC tools look for custom properties (Blender
        # imports the userProperties: namespace as an object's properties).
        for name, kind in (("agentId", T.Int), ("group", T.String), ("role", T.String), ("characterType", T.String)):
            key = f"{USER_PROPERTIES}{name}"
            new_attribute(spec, key, kind, v[(_ROOT, key)], U, custom=True)
        new_attribute(spec, "crowd:speed", T.Float, v[(_ROOT, "crowd:speed")], U)
        new_attribute(spec, "crowd:height", T.Float, v[(_ROOT, "crowd:height")], U)
        new_attribute(spec, "crowd:startPosition", T.Point3f, Gf.Vec3f(*v[(_ROOT, "crowd:startPosition")]), U)
        for name in ("crowd:group", "crowd:leader"):
            if (_ROOT, name) in v:
                Sdf.RelationshipSpec(spec, name, custom=False).targetPathList.explicitItems = [v[(_ROOT, name)]]
        Sdf.RelationshipSpec(spec, "skel:skeleton", custom=False).targetPathList.explicitItems = [f"{path}/Skel"]
        Sdf.RelationshipSpec(spec, "skel:animationSource", custom=False).targetPathList.explicitItems = [f"{path}/Anim"]
        if a.role[i] == _INVISIBLE:
            new_attribute(spec, "visibility", T.Token, "invisible")
        self._place(spec, path)
        for name in _STATE:
            new_attribute(spec, name, T.Token, custom=True)
        new_attribute(spec, "crowd:pathMethod", T.Token, None, U, custom=True)

        skel = new_prim(layer, f"{path}/Skel", "Skeleton", Sdf.SpecifierDef)
        skel.referenceList.prependedItems = self._skeleton
        anim = new_prim(layer, f"{path}/Anim", "SkelAnimation", Sdf.SpecifierDef)
        new_attribute(anim, "joints", T.TokenArray, self._joints, U)
        s = v[(_ANIM, "scales")]
        new_attribute(anim, "scales", T.Half3Array, Vt.Vec3hArray([Gf.Vec3h(s, s, s), Gf.Vec3h(1, 1, 1), Gf.Vec3h(1, 1, 1)]))
        new_attribute(anim, "rotations", T.QuatfArray)
        new_attribute(anim, "translations", T.Float3Array)
        body = new_prim(layer, f"{path}/Body", "Mesh", Sdf.SpecifierDef)
        body.referenceList.prependedItems = self._body
        set_palette(body, self.palette[i])
        # Height for shaders and tools; the geometry is scaled by the root joint.
        new_attribute(body, "primvars:crowd:height", T.Float, v[(_BODY, "primvars:crowd:height")]).SetInfo(
            "interpolation", "constant")
        return spec

    # -- placement ------------------------------------------------------------------------------------
    def _place(self, spec, path: str) -> None:
        """The agent's transform: the root joint holds its world motion in canonical metres, so the
        SkelRoot maps canonical metres to the stage's axes and units and undoes its parent's transform
        (:mod:`usdcrowd.scenario.parent_space`). The order replaces the placement the scenario may have
        authored, which only said where the agent starts."""
        from pxr import Sdf

        T = Sdf.ValueTypeNames
        key = parent_key(path)
        if key not in self._placements:
            self._placements[key] = self._placement(key)
        ops, value = self._placements[key]
        if isinstance(value, list):         # an animated parent: the inverse follows it
            attr = new_attribute(spec, "xformOp:transform:stageFrame", T.Matrix4d)
            for t, mt in value:
                self.layer.SetTimeSample(attr.path, t, mt)
        elif value is not None:
            new_attribute(spec, "xformOp:transform:stageFrame", T.Matrix4d, value)
        new_attribute(spec, "xformOpOrder", T.TokenArray, ops, Sdf.VariabilityUniform)

    def _placement(self, key: str):
        """``(xformOpOrder, the stage-frame op's value)`` of the agents under the parent ``key``: None
        (no op), a Gf.Matrix4d, or ``[(time, Gf.Matrix4d), ...]`` for a parent that moves."""
        from pxr import Gf, Vt

        m = in_parent(self.frame.from_canonical, self.parents.get(key))
        if m.ndim == 3:
            value = [(float(t), Gf.Matrix4d(mt.tolist())) for t, mt in zip(self.scenario.time.codes, m)]
        elif not is_identity(m):
            value = Gf.Matrix4d(m.tolist())
        else:
            return Vt.TokenArray([]), None
        return Vt.TokenArray(["xformOp:transform:stageFrame"]), value
