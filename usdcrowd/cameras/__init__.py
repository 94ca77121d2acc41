"""Cameras that film the crowd: seed 000's steering camera agents and simpler behaviors.

Pure numpy/scipy on arrays (no USD, no renderer). Where things are:

- ``steering``: :class:`CameraAgents`, the per-step loop (modes, Algorithms 1 and 2);
- ``forces``: framing, obstacle avoidance (Algorithm 3), separation
  (Algorithm 4), wandering, containment, crane elevation;
- ``torques``: aiming (Algorithm 5), camera avoidance (Algorithm 6);
- ``framing``: the constant-angle arcs and Bezier range of viewpoints;
- ``frustum``: points in frusta, the 2D frustum intersection test;
- ``orientation``: quaternions of camera frames, levelling, integration;
- ``film``: a whole shot through the agents, to :class:`~usdcrowd.core.model.CameraTrack`;
- ``placement``: rings, static cameras, generated camera agents;
- ``overview``: one camera that frames the whole crowd;
- ``metrics``: seed 000's activity metric and viewed ratio (Algorithm 7).
"""

import importlib

# Loaded on first use: the command line reads the behaviors' names from this package while it builds its
# parser, and must not wait for scipy (nor have a Ctrl-C land in its import) to do so.
# (``film`` the function is imported from ``film`` the module: here the name would be one or the other
# depending on what was imported first.)
_WHERE = {"CameraParams": "params", "generated_agents": "placement", "overview_track": "overview",
          "static_cameras": "placement"}

__all__ = sorted(_WHERE)


def __getattr__(name):
    if name not in _WHERE:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f".{_WHERE[name]}", __name__), name)
