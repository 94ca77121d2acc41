"""Resource bounds accepted by default, so no input can make a command run away.

Each is checked before the work it bounds starts and refused with a one-line
error that names the option raising it (``--max-agents``, ``--max-frames``,
``--max-image-pixels``), for users who mean it.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Limits:
    """Largest inputs accepted.

    Attributes
    ----------
    max_agents : int
        Agents in a scenario (authored plus clones). 100,000 agents x 240
        frames is about 40 GB of crowd layer.
    max_frames : int
        Frames in a shot (an hour at 24 fps is 86,400).
    max_image_pixels : int
        Pixels of a behavior-map image (8192 x 8192; read as float32, 256 MiB).
    """

    max_agents: int = 100_000
    max_frames: int = 100_000
    max_image_pixels: int = 8192 * 8192


DEFAULT = Limits()

# Deepest prim path accepted (USD itself has no bound; writing a layer costs the square of the depth:
# 10,000 nested prims hung simulate). DCC scenes rarely go past 30.
MAX_PRIM_DEPTH = 256
