"""Tunable constants of the camera agents, with units, in one place.

The per-camera limits (maximum speed, force and angular speed, arrival
distance, aiming threshold, separation distance, view angle, elevation) are
authored on each camera with CameraAgentAPI; what follows is shared by all
cameras of a run.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class CameraParams:
    """Weights and ranges of seed 000's forces and torques.

    Attributes
    ----------
    substeps : int
        Integration steps per frame (Algorithm 1's Euler step is 1 / (fps x substeps)).
    w_framing, w_obstacle, w_separation, w_wander, w_containment, w_elevation : float
        Weights of the steering forces in the sum (section 4.3).
    w_aim, w_avoid, w_wander_torque : float
        Weights of the torques (section 4.4).
    force_gain : float
        1/s: the forces are velocity differences (Reynolds' desired minus
        current velocity); this turns their sum into an acceleration before
        the maxForce limit (at 1/s a camera would lag a second behind).
    crane_share : float
        Share of maxForce a vertical (crane) move may take before horizontal moves get the rest (at 1, a
        camera rising or sinking at full force could not steer aside from people walking at it).
    angular_gain : float
        1/s: how fast the rotational velocity follows a torque's desired one
        (the ``q_dot_d q_dot_c^-1`` products of Algorithms 5 and 6 scaled per second).
    beta_deg : float
        Degrees: below this angle at a circle's centre the framing range is a
        Bezier curve (Figure 7), so no shot is taken from next to A or B.
    min_frame_width : float
        Metres: a single character is framed as this wide.
    crane_members : int
        Events with at least this many members are filmed from a crane
        elevation that grows with their radius.
    crane_gain : float
        Metres of camera height per metre of event radius (crane shots).
    frame_radius : float
        Metres: an event spread wider than this round its centre is framed by its densest part (the
        members within this of the one with the most others that near).
    look_height : float
        Metres above the ground the cameras aim at (chest height).
    scout_range : float
        Metres: a scouting camera notices events up to this far in its frustum.
    avoid_near : float
        Metres: overlaps of frusta closer than this to either camera do not
        count (Algorithm 6's near plane).
    avoid_range : float
        Metres: frusta are tested for overlap (Algorithm 6) up to this far;
        cameras further apart than twice this are never paired.
    obstacle_range : float
        Metres: obstacles further than this are not considered (Algorithm 3).
    obstacle_min_height : float
        Metres: lower scenery (kerbs, bollards) cannot hide a person.
    obstacle_clearance : float
        Metres kept between a camera and scenery it flies beside.
    bounds_margin : float
        Metres kept inside the scene's bounds.
    bounds_braking : float
        Share of maxForce a camera brakes with as it nears the bounds (it stops at their margin, not
        against it: stopped there by the hard limit, it would brake harder than maxForce).
    wander_jitter : float
        Radians per second of random change of the wandering direction (Reynolds 1999).
    wander_speed : float
        Share of the maximum speed used while wandering.
    wander_look_distance : float
        Metres ahead along its wandering direction a scouting camera aims at
        (at ``look_height``): the wandering torque.
    wander_turn : float
        Radians per second a scout's wandering direction turns toward the
        crowd's centre while it is beyond the containment radius, points
        out of the scene's bounds, or looks at a point scenery hides.
    occlusion_lookahead : float
        Seconds ahead a tracking camera checks whether people walking on
        will hide its event (it cranes up before they do).
    sight_interval : float
        Seconds between a tracking camera's checks of what hides its event.
    sight_people : int
        At most this many of an event's people are checked (evenly picked).
    sight_occluders : int
        The people nearest the event (within 3 m of its area) who may hide it, at most this many.
    steepest_deg : float
        Degrees: a tracking camera stands no higher than lets it look down at its event at this angle
        (right over its event it could not pan with people walking under it).
    lift_hold : float
        Seconds a tracking camera takes to come down from the top of its
        elevation range once its event is in clear view again.
    seek_below : float
        A tracking camera that sees under this share of its event's people looks for a clearer bearing
        round the event.
    seek_bearings : tuple of float
        Degrees: the bearings round the event, from the camera's own, it checks.
    seek_turn_cost : float
        Share of the event's people a half turn round the event is worth (nearer bearings first).
    seek_gain : float
        A bearing is sought when it sees at least this share more of the event's people.
    seek_seconds : float
        Seconds a camera keeps seeking one bearing before it checks again.
    ready_seconds : float
        A camera with an authored target turns to where its event will begin this many seconds before.
    give_up_seconds : float
        A tracking camera that has seen none of its event's people this long leaves it (and does not take
        it again for as long).
    take_share : float
        A scout takes an event when at least this share of the people of it in its frame are clear of
        scenery, now and ``occlusion_lookahead`` on (and at least one).
    contain_margin : float
        Metres beyond the crowd's extent where containment starts pulling back.
    min_track_seconds : float
        A camera that shares its event with others may leave it for one that
        nobody follows once it has tracked it this long.
    """

    substeps: int = 2
    w_framing: float = 1.0
    w_obstacle: float = 0.6
    w_separation: float = 0.8
    w_wander: float = 0.5
    w_containment: float = 1.0
    w_elevation: float = 1.0
    w_aim: float = 1.0
    w_avoid: float = 0.4
    w_wander_torque: float = 1.0
    force_gain: float = 3.0
    crane_share: float = 0.8
    angular_gain: float = 4.0
    beta_deg: float = 80.0
    min_frame_width: float = 0.6
    crane_members: int = 8
    crane_gain: float = 0.6
    frame_radius: float = 10.0
    look_height: float = 1.1
    scout_range: float = 60.0
    avoid_near: float = 1.0
    avoid_range: float = 25.0
    obstacle_range: float = 40.0
    obstacle_min_height: float = 1.2
    obstacle_clearance: float = 0.6
    bounds_margin: float = 0.5
    bounds_braking: float = 0.8
    wander_jitter: float = 1.5
    wander_speed: float = 0.6
    wander_look_distance: float = 15.0
    wander_turn: float = 1.5
    occlusion_lookahead: float = 1.5
    sight_interval: float = 0.25
    sight_people: int = 12
    sight_occluders: int = 64
    steepest_deg: float = 55.0
    lift_hold: float = 8.0
    seek_below: float = 0.75
    seek_bearings: tuple = (-30.0, 30.0, -60.0, 60.0, -90.0, 90.0, -135.0, 135.0, 180.0)
    seek_turn_cost: float = 0.2
    seek_gain: float = 0.25
    seek_seconds: float = 6.0
    give_up_seconds: float = 2.5
    ready_seconds: float = 4.0
    take_share: float = 1.0 / 3.0
    contain_margin: float = 10.0
    min_track_seconds: float = 3.0
