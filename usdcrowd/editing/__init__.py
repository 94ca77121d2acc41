"""A director for a shot's cameras: the edited cut (seed 000, section 6's future work).

Pure numpy on arrays (no USD, no renderer), like :mod:`usdcrowd.cameras`.
Where things are:

- ``params``: the director's rules and weights, with units, in one place;
- ``importance``: how much each event matters at each frame (unique before
  repetitive, new before long-running, larger before smaller, the user's weights);
- ``coverage``: how well each camera shows each event at each frame (members
  visible, not hidden by scenery or people, and large enough to read);
- ``rules``: the 30-degree and 180-degree rules between two shots of one event;
- ``director``: the cut itself, planned over the whole shot (shots held 2-8 s,
  no cut the rules forbid, a cost per cut).
"""

from .director import Cut, Shot, plan_cut
from .params import EditParams

__all__ = ["Cut", "EditParams", "Shot", "plan_cut"]
