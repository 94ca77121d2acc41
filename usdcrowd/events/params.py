"""Thresholds of the event detector (seed 000, section 4.1), with their units.

Defaults suit pedestrians filmed at 24 fps. Durations are in seconds and
turned into whole frames with :meth:`EventParams.frames`, so the same
parameters work at any frame rate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields


@dataclass(frozen=True)
class EventParams:
    """Every threshold of the event detector.

    One-to-one interaction (two characters face each other without moving)
    -----------------------------------------------------------------------
    interaction_distance : float
        Largest distance between the two, metres (2.0).
    interaction_speed : float
        Largest planar speed of either of them, m/s (0.3; the simulation lets
        resting people jostle up to 0.3 m/s).
    interaction_facing : float
        Largest angle between each one's heading and the direction to the
        other, degrees (35).
    interaction_min_duration : float
        Shortest interaction kept, seconds (2.0).
    interaction_gap : float
        Longest time the test may fail without ending the interaction
        (hysteresis against blips), seconds (0.25 = 6 frames at 24 fps). The
        event ends on the last frame the test held.
    interaction_margin : float
        Added to half the distance between the two to give the radius, metres
        (0.5).

    Group motion on the multi-resolution grid (quad-tree)
    -----------------------------------------------------
    cell_size : float
        Side of the finest cells, metres (4.0); level ``L`` cells are
        ``2**L`` times larger.
    levels : int
        Number of quad-tree levels (4: 4, 8, 16 and 32 m cells).
    min_alignment : float
        Least length of a cell's mean unit velocity, in [0, 1] (0.8).
    min_speed : float
        Least mean speed of a cell's agents, m/s (0.5).
    max_speed_cv : float
        Largest coefficient of variation (std / mean) of the speeds in a cell
        (0.35): the speed homogeneity.
    min_density : float
        Least number of agents per square metre of a cell (0.1: seven agents
        in an 8 m cell, 26 in a 16 m cell).
    min_type_share : float
        Least share of a cell's agents of its majority character type (0.8):
        the type homogeneity.
    cell_min_agents : int
        Least number of agents in a cell that forms a group motion, whatever
        the density (3: in a 4 m cell, two walkers that happen to share a
        heading are no group).
    merge_angle : float
        Largest angle between the mean directions of two linked cells
        (8-neighbours at one level; a cell and its parent, or the parent of
        one of its 8-neighbours) merged into one group, degrees (30).
    merge_speed_ratio : float
        Largest ratio of the faster to the slower mean speed of two merged
        cells (1.5).
    member_angle : float
        Largest angle between an agent's own direction of motion and its
        group's mean direction, degrees (30); agents of a group cell that do
        not move with the group are left out, and agents nearby that do are
        taken in, with it.
    member_speed_ratio : float
        Largest ratio between an agent's speed and its group's mean speed,
        either way (1.6).
    halo_distance : float
        Agents of the finest cells next to a group's cells join the group when
        they move with it and stand within this distance of the box around
        the group's members in the neighbouring cell, metres (1.5; 0 turns
        it off). It keeps a formation whole when a cell border cuts it or
        passers-by spoil one of its cells.
    member_levels : int
        Agents join groups through marked cells of the finest
        ``member_levels`` levels (2: 4 and 8 m cells, so a sparse group cut
        by cell borders into cells of one or two is still seen); coarser
        marked cells only link finer ones, since their agents can be far
        apart.
    min_members_create : int
        Least number of members of a group that starts a new event (5).
    min_members_keep : int
        Least number of members of the group that keeps an event running (3);
        below it (for longer than ``group_gap``) the event ends.
    match_overlap : float
        Least overlap coefficient ``|G & E| / min(|G|, |E|)`` between a
        frame's group ``G`` and the current members ``E`` of a running event
        for ``G`` to continue that event (0.5).
    coast : float
        Longest time an event may go on without a detected group, carried by
        those of its own members that still move together (at least
        ``min_members_keep`` of them, within ``member_angle`` and
        ``member_speed_ratio`` of their mean motion, at ``min_speed`` or
        more), seconds (2.0). Only events already detected for
        ``group_min_duration`` coast. The grid misses a small group cut by
        cell borders, or one whose cells passers-by spoil, for a moment; the
        paper's groups are "continuously updated over time".
    group_gap : float
        Longest time an event may go without a group that continues it
        (detected or coasting), seconds (0.5). The event ends on the last
        frame it had one.
    member_gap : float
        Membership hysteresis: a member missing from the event's group for at
        most this long stays a current member and counts as active through the
        gap, seconds (1.0).
    group_min_duration : float
        Shortest group-motion event kept at the end, seconds (1.0).
    group_margin : float
        Added to the largest member distance from the centre to give the
        radius, metres (0.5).
    """

    # --- one-to-one interaction ---
    interaction_distance: float = 2.0  # m
    interaction_speed: float = 0.3  # m/s
    interaction_facing: float = 35.0  # deg
    interaction_min_duration: float = 2.0  # s
    interaction_gap: float = 0.25  # s
    interaction_margin: float = 0.5  # m
    # --- group motion: per cell ---
    cell_size: float = 4.0  # m
    levels: int = 4
    min_alignment: float = 0.8  # [0, 1]
    min_speed: float = 0.5  # m/s
    max_speed_cv: float = 0.35
    min_density: float = 0.1  # agents / m^2
    min_type_share: float = 0.8  # [0, 1]
    cell_min_agents: int = 3
    # --- group motion: grouping cells and members ---
    merge_angle: float = 30.0  # deg
    merge_speed_ratio: float = 1.5
    member_angle: float = 30.0  # deg
    member_speed_ratio: float = 1.6
    halo_distance: float = 1.5  # m
    member_levels: int = 2
    # --- group motion: tracking ---
    min_members_create: int = 5
    min_members_keep: int = 3
    match_overlap: float = 0.5
    coast: float = 2.0  # s
    group_gap: float = 0.5  # s
    member_gap: float = 1.0  # s
    group_min_duration: float = 1.0  # s
    group_margin: float = 0.5  # m

    def __post_init__(self):
        for f in fields(self):
            v = getattr(self, f.name)
            if not (isinstance(v, (int, float)) and math.isfinite(v)) or v < 0:
                raise ValueError(f"EventParams.{f.name} must be a finite number >= 0, got {v!r}")
        if self.levels < 1 or int(self.levels) != self.levels:
            raise ValueError(f"EventParams.levels must be an integer >= 1, got {self.levels!r}")
        for name in ("interaction_distance", "cell_size", "merge_speed_ratio", "member_speed_ratio"):
            if getattr(self, name) <= 0:
                raise ValueError(f"EventParams.{name} must be > 0")
        if self.merge_speed_ratio < 1 or self.member_speed_ratio < 1:
            raise ValueError("EventParams speed ratios must be >= 1")
        if self.min_members_keep < 1 or self.min_members_create < self.min_members_keep:
            raise ValueError("EventParams needs 1 <= min_members_keep <= min_members_create")

    @staticmethod
    def frames(seconds: float, fps: float) -> int:
        """Whole frames in ``seconds`` at ``fps`` (rounded to nearest)."""
        return int(round(seconds * fps))
