"""The crowd schemas: registration with USD, the names used in code, and what is an agent.

The schemas are codeless (schemas/schema.usda -> generatedSchema.usda and
plugInfo.json), so registering the plugin folder is all USD needs. It must
happen before the first stage is opened, which is why ``import usdcrowd``
calls :func:`register`.
"""

from __future__ import annotations

from .core.resources import data_dir

# Schema type names as they appear in .usda files.
GROUP = "CrowdGroup"
AGENT_API = "CrowdAgentAPI"
BEHAVIOR_LAYER = "BehaviorLayer"
INTEREST_POINT = "InterestPoint"
EVENT = "CrowdEvent"
CAMERA_AGENT_API = "CameraAgentAPI"
TORIC_CAMERA_API = "ToricCameraAPI"
CUT_CAMERA_API = "CutCameraAPI"
SCENERY_API = "CrowdSceneryAPI"

# What a tool without our schemas should see each typed schema as (USD's
# ``fallbackPrimTypes`` stage metadata, read from the root layer): without
# it Blender drops CrowdGroup prims, so their agents lose their parent, its
# name and the stage's axis and unit conversion. Groups become transforms;
# layers and events, which hold only data, scopes.
FALLBACK_PRIM_TYPES = {GROUP: ["Xform"], INTEREST_POINT: ["Xform"], BEHAVIOR_LAYER: ["Scope"], EVENT: ["Scope"]}

_registered = False


def author_fallbacks(layer) -> None:
    """Write :data:`FALLBACK_PRIM_TYPES` into a (root) layer's metadata."""
    from pxr import Vt

    layer.pseudoRoot.SetInfo("fallbackPrimTypes", {k: Vt.TokenArray(v) for k, v in FALLBACK_PRIM_TYPES.items()})


def register() -> None:
    """Register usdcrowd's schema plugin with USD's plugin registry (idempotent).

    Works alongside a user's own ``PXR_PLUGINPATH_NAME``: those plugins were
    found when ``pxr`` loaded, ours are added explicitly here.
    """
    global _registered
    if _registered:
        return
    from pxr import Plug

    Plug.Registry().RegisterPlugins([str(data_dir("schemas"))])
    _registered = True


def is_group(prim) -> bool:
    return prim.GetTypeName() == GROUP


def is_agent(prim) -> bool:
    """True for a prim authored as an agent with our schema (CrowdAgentAPI).

    Readers of shots ask :func:`agent_id` instead, which also knows agents
    that came back from a DCC tool without the schema.
    """
    return prim.HasAPI(AGENT_API)


# Where usdcrowd writes an agent's facts again for tools without our schemas
# (usd/crowd_layer.py). Blender imports ``userProperties:crowd:agentId`` as an
# object property named ``crowd:agentId`` and exports it back under that name,
# so a fact may come back under either.
USER_PROPERTIES = "userProperties:crowd:"


def crowd_value(prim, name: str):
    """An agent's crowd fact ``name``, wherever the stage keeps it.

    Parameters
    ----------
    prim : Usd.Prim
    name : str
        The fact without namespace: ``"agentId"``, ``"group"``, ``"role"``...

    Returns
    -------
    object or None
        The value of ``crowd:<name>`` (our schema's attribute, fallback
        included, or a custom property of that name), else of
        ``userProperties:crowd:<name>``; None where neither has a value.
    """
    for attr_name in ("crowd:" + name, USER_PROPERTIES + name):
        attr = prim.GetAttribute(attr_name)
        value = attr.Get() if attr else None
        if value is not None:
            return value
    return None


def agent_id(prim) -> int | None:
    """The track id of ``prim`` if it is an agent, None if it is not.

    The one test every reader of shots uses (renderers, ground truth,
    ``inspect``, ``validate``). An agent is either

    - a prim with CrowdAgentAPI: its ``crowd:agentId`` (-1 in a scenario
      that leaves the numbering to usdcrowd), or
    - a transformable prim without our schemas that carries a whole-number
      ``crowd:agentId`` or ``userProperties:crowd:agentId`` custom property:
      a shot exported back out of a DCC tool (Blender writes what it imported
      as custom properties on the agent's SkelRoot). Its id is the one
      usdcrowd gave it, so tracks keep their ids through the round trip.

    Neither the prim's place in the hierarchy nor its transform matters.
    """
    from pxr import UsdGeom

    if is_agent(prim):
        value = prim.GetAttribute("crowd:agentId").Get()
        return -1 if value is None else int(value)
    if not prim.IsA(UsdGeom.Xformable) or prim.GetTypeName() in _NOT_AGENTS:
        return None
    return _whole_number(crowd_value(prim, "agentId"))


# Our typed schemas that are transformable but never an agent, whatever they carry.
_NOT_AGENTS = (GROUP, INTEREST_POINT)


def _whole_number(value) -> int | None:
    """``value`` as an int when it is a whole number (DCC tools may keep integers as doubles), else None."""
    if isinstance(value, bool) or value is None:
        return None
    try:
        number = float(value)
    except (TypeError, ValueError):
        return None
    return int(number) if number.is_integer() else None


def agent_group(prim) -> str:
    """Path of an agent's group: its ``crowd:group`` target, else the group path it carries as a custom
    property (groups do not survive a DCC tool's round trip), else its parent prim."""
    rel = prim.GetRelationship("crowd:group")
    targets = rel.GetTargets() if rel else []
    if targets:
        return str(targets[0])
    carried = crowd_value(prim, "group")
    return str(carried) if carried else str(prim.GetParent().GetPath())


def agent_prims(stage) -> list:
    """(prim, id) of every agent of ``stage`` (:func:`agent_id`), in stage order.

    An agent's descendants are not searched: its skeleton and body are part of it.
    """
    from pxr import Usd

    out = []
    it = iter(Usd.PrimRange(stage.GetPseudoRoot(), Usd.TraverseInstanceProxies()))
    for prim in it:
        aid = agent_id(prim)
        if aid is not None:
            out.append((prim, aid))
            it.PruneChildren()
    return out
