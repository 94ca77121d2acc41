"""The pure data core: a scenario and a simulated crowd as plain numpy arrays.

Nothing here imports ``pxr``. :mod:`usdcrowd.scenario` fills a
:class:`Scenario` from a stage; :mod:`usdcrowd.sim` turns it into
:class:`CrowdFrames`; :mod:`usdcrowd.usd` writes those back as time samples.

Conventions (everywhere in usdcrowd's arrays):

- metres, Z up, right-handed; the ground is the XY plane at z = 0 unless a
  height layer says otherwise;
- headings are yaw angles in radians about +Z, 0 facing +X;
- categorical attributes are small integer codes indexing the vocabularies
  below, so that simulation code can compare them vectorised.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

# Vocabularies: the index of a token is its code. They match the schema's
# allowedTokens (less "random", which the resolver replaces by a draw).
CHARACTER_TYPES = ("human", "herbivore", "ant", "bird")
PERSONALITIES = ("civilian", "security", "attacker", "herbivore", "predator")
BEHAVIORS = ("walk", "run", "rest", "wander", "visit", "graze", "flock")
CONDITIONS = ("grouped", "isolated")
FEAR_RESPONSES = ("flee", "freeze")
VISIT_PROFILES = ("detailed", "casual", "timeLimited")
ROLES = ("member", "leader", "invisibleLeader")
LAYER_MEANINGS = ("height", "damage", "food", "forbidden", "interest", "rest")
LAYER_GENERATORS = ("painted", "explosion", "volcano", "food")
PATH_METHODS = ("direct", "bezier", "gradient")
# Simulation output vocabularies.
ANIM_CLASSES = ("idle", "walk", "run", "strideLeft", "strideRight")
HEALTH_STATES = ("ok", "wounded", "dead")


def code(vocabulary: tuple[str, ...], token: str) -> int:
    """Integer code of ``token`` in ``vocabulary`` (ValueError if absent)."""
    return vocabulary.index(token)


@dataclass
class TimeRange:
    """The shot's time codes: frames ``start..end`` inclusive at ``fps``."""

    start: float = 1.0
    end: float = 240.0
    fps: float = 24.0

    @property
    def n_frames(self) -> int:
        return int(round(self.end - self.start)) + 1

    @property
    def codes(self) -> np.ndarray:
        """(n_frames,) float64 time codes."""
        return self.start + np.arange(self.n_frames, dtype=np.float64)


@dataclass
class GroupTable:
    """One row per CrowdGroup, in stage traversal order (parents first).

    Attributes
    ----------
    path : list[str]
        Prim paths.
    parent : (g,) int32
        Row of the enclosing group, -1 at the top.
    goal : (g, 3) float64
        Where the group walks, metres; NaN rows for groups with no goal.
    visit_budget : (g,) float64
        Seconds a timeLimited group spends before leaving.
    leader : (g,) int32
        Agent row of the group's leader, -1 if none.
    waypoints : list of ((k,) float64, (k, 3) float64) or None
        Per group, when its goal (own or inherited) is time-sampled: the time
        codes and the points (metres); each point is the goal from its time
        on. None for a static goal. An empty list: no group has waypoints.
    """

    path: list[str]
    parent: np.ndarray
    goal: np.ndarray
    visit_budget: np.ndarray
    leader: np.ndarray
    waypoints: list = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.path)


@dataclass
class AgentTable:
    """One row per agent with every attribute resolved (seed 004, section 2).

    Attributes
    ----------
    path : list[str]
        Prim path of the agent's SkelRoot (authored, or the one the clone
        will be written at).
    agent_id : (n,) int32
        Track id, unique, >= 1.
    group : (n,) int32
        Row in :class:`GroupTable`.
    leader : (n,) int32
        Row of the agent followed, -1 if none.
    role, character_type, personality, behavior, condition, fear_response,
    visit_profile : (n,) int8
        Codes into ROLES, CHARACTER_TYPES, ...
    speed : (n,) float64
        Preferred speed, m/s.
    height : (n,) float64
        Body height, metres.
    max_slope : (n,) float64
        Steepest climbable slope, rise over run.
    map_influence : (n,) float64
        Weight of behavior-map reactions, [0, 1].
    color : (n, 3) float64
        Linear RGB clothing colour.
    start : (n, 3) float64
        Start position, metres.
    start_heading : (n,) float64
        Start yaw, radians.
    trades : (n,) bool
        Market trading (crowd:trades): wanderers stop to trade with resting
        agents of another top-level group. None: nobody trades.
    palette : (n, r, 3) float64
        Linear RGB per body region (character.body.REGIONS: top, trousers,
        skin, hair, shoes). None: the clothing colour as the top and plain
        other regions (character.appearance.plain_palettes).
    """

    path: list[str]
    agent_id: np.ndarray
    group: np.ndarray
    leader: np.ndarray
    role: np.ndarray
    character_type: np.ndarray
    personality: np.ndarray
    behavior: np.ndarray
    condition: np.ndarray
    fear_response: np.ndarray
    visit_profile: np.ndarray
    speed: np.ndarray
    height: np.ndarray
    max_slope: np.ndarray
    map_influence: np.ndarray
    color: np.ndarray
    start: np.ndarray
    start_heading: np.ndarray
    trades: np.ndarray | None = None
    palette: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.path)

    @property
    def visible(self) -> np.ndarray:
        """(n,) bool: agents that are rendered (not invisible leaders)."""
        return self.role != code(ROLES, "invisibleLeader")


@dataclass
class BehaviorField:
    """A behavior layer (seed 004) as a grid of values on the ground.

    Attributes
    ----------
    path : str
        Prim path of the BehaviorLayer.
    meaning : int
        Code into LAYER_MEANINGS.
    generator : int
        Code into LAYER_GENERATORS.
    values : (h, w) float32 or None
        Values already mapped through the layer's value range; row 0 is the
        +Y edge. None for generated layers until the simulation makes them.
    extent_min, extent_max : (2,) float64
        World XY of the lower-left and upper-right corners, metres.
    influence : float
        Weight in [0, 1].
    origin : (3,) float64
        Centre of a generated layer, metres.
    radius : float
        Radius of a generated layer, metres.
    start_time : float
        Time code at which a generated layer appears.
    """

    path: str
    meaning: int
    generator: int
    values: np.ndarray | None
    extent_min: np.ndarray
    extent_max: np.ndarray
    influence: float = 1.0
    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))
    radius: float = 10.0
    start_time: float = 0.0

    def sample(self, xy: np.ndarray) -> np.ndarray:
        """Nearest-pixel values at world points.

        Parameters
        ----------
        xy : (n, 2) float
            World points, metres.

        Returns
        -------
        (n,) float32
            Values; 0 outside the extent.
        """
        h, w = self.values.shape
        u = (xy[:, 0] - self.extent_min[0]) / (self.extent_max[0] - self.extent_min[0])
        v = (self.extent_max[1] - xy[:, 1]) / (self.extent_max[1] - self.extent_min[1])
        inside = (u >= 0) & (u < 1) & (v >= 0) & (v < 1)
        col = np.clip((u * w).astype(np.int64), 0, w - 1)
        row = np.clip((v * h).astype(np.int64), 0, h - 1)
        return np.where(inside, self.values[row, col], 0.0).astype(np.float32)


@dataclass
class InterestTable:
    """Interest points (seed 003), one row each.

    Attributes
    ----------
    path : list[str]
    position : (m, 3) float64, metres
    interest, radius, visibility, prior_knowledge, decay_rate,
    view_duration : (m,) float64
    """

    path: list[str]
    position: np.ndarray
    interest: np.ndarray
    radius: np.ndarray
    visibility: np.ndarray
    prior_knowledge: np.ndarray
    decay_rate: np.ndarray
    view_duration: np.ndarray

    def __len__(self) -> int:
        return len(self.path)

    @classmethod
    def empty(cls) -> "InterestTable":
        z = np.zeros(0)
        return cls([], np.zeros((0, 3)), z, z, z, z, z, z)


@dataclass
class Obstacles:
    """Static scenery as seen by the simulation: footprints on the ground.

    Attributes
    ----------
    path : list[str]
        Prim path of each obstacle.
    polygons : list of (k, 2) float64
        Counter-clockwise convex footprint of each obstacle, metres.
    height : (o,) float64
        Top of each obstacle above the ground, metres.
    bottom : (o,) float64 or None
        Underside above the ground, metres, for raised scenery (an awning
        people walk under but that hides them from above); None: all on the
        ground.
    """

    path: list[str]
    polygons: list[np.ndarray]
    height: np.ndarray
    bottom: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.path)

    @classmethod
    def empty(cls) -> "Obstacles":
        return cls([], [], np.zeros(0))

    @property
    def segments(self) -> np.ndarray:
        """(s, 2, 2) float64: every polygon edge as (start, end)."""
        if not self.polygons:
            return np.zeros((0, 2, 2))
        return np.concatenate([np.stack([p, np.roll(p, -1, axis=0)], axis=1)
                               for p in self.polygons])


@dataclass
class Scenario:
    """Everything the simulation needs, read once from a scenario stage.

    Attributes
    ----------
    source : str
        The stage's file path (for messages).
    time : TimeRange
    seed : int
        Seed of the run; every random draw derives from it.
    groups : GroupTable
    agents : AgentTable
    fields : list[BehaviorField]
    interest : InterestTable
    obstacles : Obstacles
    bounds : (2, 2) float64
        [[xmin, ymin], [xmax, ymax]] of the walkable area, metres.
    cameras : CameraAgentTable
        The scenario's camera agents (CameraAgentAPI cameras).
    events : EventTable
        The events the user authored (detected ones belong to a shot).
    overhead : Obstacles
        Raised scenery people walk under (awnings, canopies), with its
        undersides: it hides people from cameras above it.
    """

    source: str
    time: TimeRange
    seed: int
    groups: GroupTable
    agents: AgentTable
    fields: list[BehaviorField]
    interest: InterestTable
    obstacles: Obstacles
    bounds: np.ndarray
    # Both classes are defined further down this module, hence the lambdas.
    cameras: "CameraAgentTable" = field(default_factory=lambda: CameraAgentTable.empty())
    events: "EventTable" = field(default_factory=lambda: EventTable())
    overhead: Obstacles = field(default_factory=lambda: Obstacles.empty())

    def field(self, meaning: str) -> BehaviorField | None:
        """The first behavior field with this meaning, or None."""
        m = code(LAYER_MEANINGS, meaning)
        return next((f for f in self.fields if f.meaning == m), None)


@dataclass
class CrowdFrames:
    """A simulated crowd: per-frame state of every agent.

    Arrays have a leading time axis of ``len(times)`` frames; a long shot is
    produced in chunks of consecutive frames with the same layout.

    Attributes
    ----------
    times : (t,) float64
        Time codes.
    position : (t, n, 3) float32
        Root (ground contact) position, metres.
    heading : (t, n) float32
        Facing yaw, radians.
    velocity : (t, n, 2) float32
        Planar velocity, m/s.
    behavior : (t, n) int8
        Current behavior, code into BEHAVIORS.
    anim_class : (t, n) int8
        Code into ANIM_CLASSES.
    anim_phase : (t, n) float32
        Phase of the animation cycle in [0, 1).
    health : (t, n) int8
        Code into HEALTH_STATES.
    look_at : (t, n, 3) float32
        Point the head and torso turn to, metres; NaN where none.
    path_method : (n,) int8
        Code into PATH_METHODS, per agent for the whole shot.
    present : (t, n) bool or None
        Who is in the scene at each frame (replayed tracks: people enter and
        leave); None: everyone, all the time. An absent agent's other fields
        hold where it enters or leaves, standing.
    """

    times: np.ndarray
    position: np.ndarray
    heading: np.ndarray
    velocity: np.ndarray
    behavior: np.ndarray
    anim_class: np.ndarray
    anim_phase: np.ndarray
    health: np.ndarray
    look_at: np.ndarray
    path_method: np.ndarray
    present: np.ndarray | None = None

    @property
    def n_agents(self) -> int:
        return self.position.shape[1]

    def agents(self, rows: np.ndarray) -> "CrowdFrames":
        """The frames of the agents ``rows`` ((m,) int, in that order, or a slice: cheaper), as contiguous
        copies."""
        from dataclasses import fields, replace

        def pick(name):
            a = getattr(self, name)
            return np.ascontiguousarray(a[rows] if name == "path_method" else a[:, rows])

        return replace(self, **{f.name: pick(f.name) for f in fields(self)
                                if f.name != "times" and getattr(self, f.name) is not None})

    def frames(self, key: slice) -> "CrowdFrames":
        """The frames ``key`` selects (a slice of the time axis), every agent."""
        from dataclasses import fields, replace

        return replace(self, **{f.name: getattr(self, f.name)[key] for f in fields(self)
                                if f.name != "path_method" and getattr(self, f.name) is not None})


# Events (seed 000, section 4.1) and camera agents (sections 4.2 to 4.4).
EVENT_KINDS = ("interaction", "groupMotion", "explosion", "eruption", "arrival", "dialogue")
CAMERA_MODES = ("scouting", "tracking")


@dataclass
class Event:
    """One CrowdEvent: who takes part, where, and when.

    Detected events and authored (scenario) events share this form. Samples
    cover every frame from ``start`` to ``end`` of the shot they belong to.

    Attributes
    ----------
    path : str
        Prim path of the CrowdEvent.
    kind : int
        Code into EVENT_KINDS.
    start, end : float
        First and last time code (inclusive).
    members : (k,) int32
        Agent rows of everyone who ever took part, ascending.
    times : (m,) float64
        Time codes of the samples below (``start`` .. ``end``, every frame).
    active : (m, k) bool
        ``active[i, j]``: member ``j`` takes part at ``times[i]``.
    center : (m, 3) float64
        Centre of the event, canonical metres.
    radius : (m,) float64
        Radius of the event's area, metres.
    authored : bool
        True for events the user authored in the scenario (never rewritten).
    """

    path: str
    kind: int
    start: float
    end: float
    members: np.ndarray
    times: np.ndarray
    active: np.ndarray
    center: np.ndarray
    radius: np.ndarray
    authored: bool = False

    def sample(self, time: float) -> int:
        """Index into ``times`` of ``time``, or -1 outside the event."""
        if time < self.start - 1e-6 or time > self.end + 1e-6 or len(self.times) == 0:
            return -1
        i = int(np.searchsorted(self.times, time - 1e-6))
        return min(i, len(self.times) - 1)

    def on_frames(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Where the event's samples fall among a shot's time codes ``times`` ((t,), ascending).

        Returns
        -------
        frames : (m,) int64
            Indices into ``times`` of the samples that match one.
        samples : (m,) int64
            Indices into ``self.times`` of those samples.
        """
        times = np.asarray(times, dtype=np.float64)
        if len(self.times) == 0 or len(times) == 0:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        i = np.searchsorted(times, self.times - 1e-6)
        ok = i < len(times)
        ok[ok] &= np.abs(times[i[ok]] - self.times[ok]) < 1e-6
        return i[ok], np.flatnonzero(ok)

    def members_at(self, time: float) -> np.ndarray:
        """(j,) int32 agent rows taking part at ``time`` (empty outside)."""
        i = self.sample(time)
        return self.members[self.active[i]] if i >= 0 else np.zeros(0, np.int32)


@dataclass
class EventTable:
    """Every event of a shot, in a stable order (authored first, then detected by id)."""

    events: list[Event] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.events)

    def __iter__(self):
        return iter(self.events)

    def __getitem__(self, i) -> Event:
        return self.events[i]

    @property
    def paths(self) -> list[str]:
        return [e.path for e in self.events]

    def active_at(self, time: float) -> list[int]:
        """Rows of the events running at ``time``."""
        return [i for i, e in enumerate(self.events) if e.start - 1e-6 <= time <= e.end + 1e-6]

    def agent_events(self, time: float, n_agents: int) -> list[list[int]]:
        """Per agent row, the rows of the events it takes part in at ``time``."""
        out: list[list[int]] = [[] for _ in range(n_agents)]
        for i in self.active_at(time):
            for a in self.events[i].members_at(time):
                out[int(a)].append(i)
        return out


@dataclass
class CameraAgentTable:
    """Camera agents (CameraAgentAPI cameras), one row each, initial state.

    Attributes
    ----------
    path : list[str]
        Prim paths of the UsdGeom.Camera prims.
    cam_to_world : (c, 4, 4) float64
        Initial camera-to-world, canonical metres, row vectors; the camera
        looks down its local -Z with +Y up.
    focal_length, horizontal_aperture, vertical_aperture : (c,) float64
        Lens values as authored (only their ratios matter here).
    near, far : (c,) float64
        Clipping range, metres.
    mode : (c,) int8
        Initial mode, code into CAMERA_MODES.
    max_speed : (c,) float64
        m/s.
    max_force : (c,) float64
        m/s^2.
    max_angular_speed : (c,) float64
        Radians per second (alpha max).
    arrival_distance : (c,) float64
        Metres.
    aim_threshold : (c,) float64
        Radians (alpha t).
    separation_distance : (c,) float64
        Metres (d max).
    view_angle : (c,) float64
        Share of the field of view the event subtends, in (0, 1).
    elevation : (c, 2) float64
        Lowest and highest camera height, metres.
    target : list[str | None]
        Prim path of the CrowdEvent or agent tracked, None if unauthored.
    """

    path: list[str]
    cam_to_world: np.ndarray
    focal_length: np.ndarray
    horizontal_aperture: np.ndarray
    vertical_aperture: np.ndarray
    near: np.ndarray
    far: np.ndarray
    mode: np.ndarray
    max_speed: np.ndarray
    max_force: np.ndarray
    max_angular_speed: np.ndarray
    arrival_distance: np.ndarray
    aim_threshold: np.ndarray
    separation_distance: np.ndarray
    view_angle: np.ndarray
    elevation: np.ndarray
    target: list

    def __len__(self) -> int:
        return len(self.path)

    @classmethod
    def empty(cls) -> "CameraAgentTable":
        z = np.zeros(0)
        return cls([], np.zeros((0, 4, 4)), z, z, z, z, z, np.zeros(0, np.int8), z, z, z, z, z, z, z,
                   np.zeros((0, 2)), [])


@dataclass
class CameraTrack:
    """A camera's trajectory, ready to author as a UsdGeom.Camera.

    Attributes
    ----------
    path : str
        Prim path of the camera.
    times : (t,) float64
        Time codes.
    cam_to_world : (t, 4, 4) float64
        Camera-to-world, canonical metres, row vectors (-Z forward, +Y up).
    focal_length : (t,) float64
        Lens focal length (same unit as the apertures).
    horizontal_aperture, vertical_aperture : float
    near, far : float
        Clipping range, metres.
    state : (t,) int8 or None
        Code into CAMERA_MODES per frame (camera agents only).
    tracked : list[str] or None
        Per frame, the CrowdEvent path tracked, "" while scouting.
    agent : CameraAgentTable row as a dict, or None
        CameraAgentAPI values to author on the camera.
    """

    path: str
    times: np.ndarray
    cam_to_world: np.ndarray
    focal_length: np.ndarray
    horizontal_aperture: float
    vertical_aperture: float
    near: float = 0.1
    far: float = 1000.0
    state: np.ndarray | None = None
    tracked: list | None = None
    agent: dict | None = None
