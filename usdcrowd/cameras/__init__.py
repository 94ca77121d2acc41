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

from .film import film
from .overview import overview_track
from .params import CameraParams
from .placement import generated_agents, static_cameras

__all__ = ["CameraParams", "film", "generated_agents", "overview_track", "static_cameras"]
