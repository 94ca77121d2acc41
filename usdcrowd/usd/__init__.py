"""Authoring results as USD: the only writer of generated layers."""

from .crowd_layer import CrowdLayerWriter
from .cameras import CAMERAS, write_camera_tracks
from .events import author_events
from .shot import CROWD, SHOT, write_shot

__all__ = ["CAMERAS", "CROWD", "SHOT", "CrowdLayerWriter", "author_events", "write_camera_tracks", "write_shot"]
