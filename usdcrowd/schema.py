"""The crowd schemas: registration with USD and the names used in code.

The schemas are codeless (schemas/schema.usda -> generatedSchema.usda and
plugInfo.json), so registering the plugin folder is all USD needs. It must
happen before the first stage is opened, which is why ``import usdcrowd``
calls :func:`register`.
"""

from __future__ import annotations

from .resources import data_dir

# Schema type names as they appear in .usda files.
GROUP = "CrowdGroup"
AGENT_API = "CrowdAgentAPI"
BEHAVIOR_LAYER = "BehaviorLayer"
INTEREST_POINT = "InterestPoint"
EVENT = "CrowdEvent"
CAMERA_AGENT_API = "CameraAgentAPI"
TORIC_CAMERA_API = "ToricCameraAPI"
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
    return prim.HasAPI(AGENT_API)
