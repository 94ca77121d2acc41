"""Authoring results as USD: the only writer of generated layers."""

from .crowd_layer import CrowdLayerWriter
from .shot import CAMERAS, CROWD, SHOT, write_cameras, write_shot

__all__ = ["CAMERAS", "CROWD", "SHOT", "CrowdLayerWriter", "write_cameras", "write_shot"]
