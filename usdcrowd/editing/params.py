"""The director's rules and weights, with units, in one place."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class EditParams:
    """What the director holds to.

    Attributes
    ----------
    min_hold, max_hold : float
        Seconds a shot lasts (the last one too). Where the cameras leave no
        choice (a single camera), a shot is held longer and the cut says so.
    decision_step : float
        Seconds between the instants a cut may happen.
    cut_cost : float
        Each cut costs as much as this many seconds of the shot's mean
        coverage: the director cuts for a clearly better view, not for a
        marginally better one.
    min_angle_deg : float
        The 30-degree rule: two consecutive shots of one event are taken from
        directions (seen from above, about the event's centre) at least this
        far apart ...
    cut_in_ratio : float
        ... unless one shows the event's people at least this many times
        larger than the other (a cut in or out along the axis).
    line_tolerance_deg : float
        The 180-degree rule: consecutive shots of one event stay on one side
        of its line of action (the two people of an interaction, or the
        direction a group walks); a camera within this angle of the line is
        on it, and may be cut to from either side.
    min_line_speed : float
        m/s: a group slower than this has no direction of travel, hence no line.
    legible_height : float
        A person this tall on screen (share of the frame's height) reads
        fully; smaller ones count in proportion.
    novelty_seconds : float
        An event's novelty halves toward its floor over about this long: new
        before long-running.
    fatigue_seconds : float
        Screen time wears an event out: its importance is divided by 1 + (seconds the cut has already
        shown it) / this, so at this many seconds shown it counts half (0: never).
    kind_weights : dict[str, float]
        Importance by event kind (``arrival``, ``groupMotion``, ...; default 1).
    event_weights : dict[str, float]
        Importance by event prim path or name, over the kind's.
    idle_weight : float
        How much a camera that shows no event scores for the people it shows
        legibly (what stays on air when nothing happens).
    """

    min_hold: float = 2.0
    max_hold: float = 8.0
    decision_step: float = 0.25
    cut_cost: float = 0.5
    min_angle_deg: float = 30.0
    cut_in_ratio: float = 2.0
    line_tolerance_deg: float = 10.0
    min_line_speed: float = 0.3
    legible_height: float = 0.12
    novelty_seconds: float = 10.0
    fatigue_seconds: float = 20.0
    kind_weights: dict = field(default_factory=dict)
    event_weights: dict = field(default_factory=dict)
    idle_weight: float = 0.1
