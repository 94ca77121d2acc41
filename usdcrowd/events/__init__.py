"""Event detection (seed 000, section 4.1): what in the crowd is worth filming.

Pure numpy/scipy, no USD, no I/O. Two kinds of events are extracted from the
simulated frames, using positions, velocities, headings and character types:

- one-to-one interaction: two visible characters face each other at
  near-zero speed, close together, for a while;
- group motion: characters moving together in the same direction, found per
  frame on a multi-resolution grid (quad-tree) from alignment, speed, speed
  homogeneity, density and type homogeneity, and followed over frames.

Public API
----------
EventParams
    Every threshold, with units and pedestrian defaults at 24 fps.
EventDetector(agents_character_type, visible, fps, params=None, scope="/World/Events")
    Streaming: ``feed(chunk)`` in time order, then ``finish() -> EventTable``.
detect_events(frames, character_type, visible, fps, params=None, scope=...)
    A whole shot at once.
find_groups(xy, velocity, character_type, params=None) -> (m,) labels
    The group motions of one frame.
find_interaction_pairs(xy, heading, speed, eligible, params=None) -> (k, 2) rows
    The facing still pairs of one frame.

Module map: ``params`` (thresholds), ``quadtree`` (per-frame group motion on
the quad-tree), ``groups`` (tracking groups into events), ``interactions``
(pairs, kd-tree, tracking), ``detector`` (the streaming detector).
"""

from __future__ import annotations

from .detector import EventDetector, detect_events
from .interactions import find_interaction_pairs
from .params import EventParams
from .quadtree import find_groups

__all__ = ["EventDetector", "EventParams", "detect_events", "find_groups", "find_interaction_pairs"]
