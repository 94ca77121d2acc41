"""Every tunable constant of the crowd simulation, in one place, with its unit.

Per-character-type tables are tuples indexed by the codes of
:data:`usdcrowd.core.model.CHARACTER_TYPES` (human, herbivore, ant, bird).

The step's compiled loops freeze these values; an edit here has them built
again (:mod:`usdcrowd.compiled`).
"""

from __future__ import annotations

import numpy as np

# --- bodies ---------------------------------------------------------------
# Collision radius of the body's footprint, metres. Ants are "scaled" ants
# (a few cm), as in the seed's animal scene; birds are small but fly.
AGENT_RADIUS = (0.25, 0.5, 0.05, 0.15)  # m
# Largest steering acceleration ("max force" per unit mass), m/s^2.
MAX_ACCEL = (4.0, 6.0, 2.0, 8.0)  # m/s^2
# Absolute speed ceiling of each type, whatever the preferred speed.
SPEED_CAP = (6.0, 12.0, 0.6, 15.0)  # m/s
# Top speed of normal motion relative to the preferred speed (catching up).
MAX_SPEED_FACTOR = 1.5
# Speed of fleeing / pursuing agents relative to the preferred speed.
PANIC_SPEED_FACTOR = 2.2
# Resting (and paralysed) agents are capped at this speed: jostled, not walking.
REST_SPEED_MAX = 0.3  # m/s
# Wounded agents move at this fraction of their speed.
WOUNDED_SPEED_FACTOR = 0.5
# Heading turn rate limit: bodies turn smoothly toward their velocity, rad/s.
TURN_RATE = (5.0, 3.0, 8.0, 4.0)  # rad/s
# Below this speed the heading stops following the velocity (jitter).
HEADING_MIN_SPEED = 0.08  # m/s
# Birds fly at a per-agent altitude drawn in this range above the ground, and
# come down to the ground when they rest (speed -> 0).
BIRD_ALTITUDE = (3.0, 8.0)  # m

# --- integration ----------------------------------------------------------
# Relaxation time of the steering (desired - current velocity) term.
TAU_RELAX = 0.5  # s
# The same for people walking by sight (vision.py) held up by someone in their way, whose desired velocity
# keeps their time gap to that person: they take up a space as it opens (calibrations of pedestrian models
# put it between 0.2 and 0.5 s; with 0.5 s the crowd in front of a door entered it a step behind the one
# before and the bottleneck flows stayed low).
SIGHT_RELAX = 0.35  # s
DEFAULT_SUBSTEPS = 2  # integration steps per frame (24 fps -> dt = 20.8 ms)
DEFAULT_CHUNK_FRAMES = 48

# --- neighbour search -----------------------------------------------------
NEIGHBOR_K = 8  # neighbours kept per agent (fixed k keeps arrays rectangular)
NEIGHBOR_RADIUS = 4.0  # m, interaction range (collision, flocking)
# Verlet skin: the list is rebuilt when someone moved more than half of it,
# or after NEIGHBOR_MAX_AGE steps, whichever comes first.
NEIGHBOR_SKIN = 0.6  # m
NEIGHBOR_MAX_AGE = 10  # steps
# Far-away position of the "ghost" row that pads missing neighbours, metres.
GHOST_POSITION = 1.0e6

# --- collision avoidance (seed 003, E_C) ----------------------------------
# sigma(t_o) = gain * exp(-t_o^2 / (2 tau^2)): a Gaussian of the expected time
# to impact, as the seed suggests (its Figure 8).
AGENT_AVOID_GAIN = 3.0  # m/s^2
AGENT_AVOID_TAU = 1.2  # s
AVOID_HORIZON = 3.0  # s, predicted-miss direction is taken at min(t_o, horizon)
# Right-hand bias of the side-step in head-on encounters (pass on the right).
PASS_RIGHT_BIAS = 0.3  # fraction of the lateral unit vector
# Personal space (Reynolds separation): acts only below this gap, so people
# walking the same way may stay close.
PERSONAL_GAP = 0.08  # m
SEPARATION_GAIN = 12.0  # m/s^2 at contact
WALL_AVOID_GAIN = 5.0  # m/s^2
WALL_AVOID_TAU = 0.8  # s
WALL_SLIDE = 0.6  # tangential share of the wall avoidance force (walk around, not into)
WALL_CONTACT_GAP = 0.10  # m, push-out below this clearance whatever the velocity
WALL_CONTACT_GAIN = 15.0  # m/s^2
# Position-based non-overlap correction after each step, fraction of the
# overlap removed per pass (Jacobi, both agents move).
OVERLAP_RELAX = 0.5
# Before the first frame, overlapping spawns are pushed apart in at most this many passes, until no two
# bodies overlap by more than the tolerance (m).
SPAWN_SEPARATION_PASSES = 500
SPAWN_OVERLAP_TOLERANCE = 0.01
# ... or until the deepest overlap has not shrunk by 1 % in this many passes (a disc too small for its clones).
SPAWN_STALL_PASSES = 50
# Metres of room kept around a pile of clones once spread out.
BOUNDS_PAD = 2.0
# Exact wall projection runs for agents whose grid clearance is below this.
WALL_PROJECT_MARGIN = 0.6  # m
# Containment (Reynolds): look-ahead time and gain at the scene bounds.
CONTAIN_LOOKAHEAD = 1.0  # s
CONTAIN_GAIN = 4.0  # 1/s^2

# Turned shoulders: in a passage narrower than two bodies, and on the way into one, people turn
# sideways, so their body across the way is its depth, not its breadth (chest depth over shoulder
# breadth, about 0.25 over 0.45 m in anthropometric tables), and two files can pass as a zipper.
SIDEWAYS_WIDTH = 0.9  # m, wall to wall: narrower than two bodies side by side (2 * 2 * AGENT_RADIUS[0]), less a hand
SIDEWAYS_AHEAD = 2.0  # m looked ahead along one's walk for such a passage
SIDEWAYS_RADIUS = 0.6  # fraction of the radius a turned body takes

# --- walking by sight (Moussaid, Helbing & Theraulaz 2011) ----------------
VISION_FIELD_DEG = 75.0  # half the field of view a walker picks its direction in
VISION_DIRECTIONS = 11  # directions tried across it
VISION_HORIZON = NEIGHBOR_RADIUS  # m, farthest a collision is looked for (the neighbour range)
VISION_TAU = 0.5  # s, time gap kept to the first person ahead
VISION_INTERVAL = 0.1  # s between a walker's looks (about a reaction time); kept in between
# Waiting one's turn (a door, a queue): a walker held below QUEUE_SPEED for QUEUE_AFTER seconds behind
# someone who is not coming toward them closes up, keeping QUEUE_TAU instead of VISION_TAU to the one
# ahead, until QUEUE_HOLD seconds after they last waited so long.
QUEUE_SPEED = 0.15  # m/s
QUEUE_AFTER = 0.5  # s
QUEUE_HOLD = 20.0  # s
QUEUE_TAU = 0.05  # s
# ... and only with no one near walking against their way faster than this (a standoff is not a queue).
COUNTERFLOW_SPEED = 0.3  # m/s

# --- flocking, velocity matching, leaders (seed 003, E_F, E_V, E_L) -------
FLOCK_RADIUS = 4.0  # m, group-mates closer than this are "visible"
COHESION_GAIN = 0.4  # 1/s^2, attraction to the mates' centre of mass
ALIGN_GAIN = 0.8  # 1/s, velocity matching
FOLLOW_DISTANCE = 1.0  # m, plus FOLLOW_DISTANCE_PER_MATE * sqrt(group size)
FOLLOW_DISTANCE_PER_MATE = 0.35  # m
FOLLOW_SLOW_RADIUS = 2.0  # m, arrive slowing radius toward the remembered leader
FOLLOW_SPEED_FACTOR = 1.4  # followers may walk this much faster to catch up
# Leaders wait for their group: speed scaled down as the mean follower
# distance exceeds the follow distance by up to this much.
LEADER_WAIT_SPREAD = 3.0  # m
LEADER_MIN_PACE = 0.15  # fraction of speed a waiting leader keeps
PERCEPTION_RANGE = 50.0  # m, nothing farther is "seen"
LOS_EVERY = 4  # followers re-check line of sight every this many steps (staggered)
TRAIL_INTERVAL = 0.4  # s between breadcrumbs of a leader's trail
TRAIL_LENGTH = 16  # breadcrumbs kept per leader
TRAIL_PROBES = (0, 1, 2, 4, 8, 15)  # breadcrumbs tried, newest first

# --- navigation / grids ---------------------------------------------------
GRID_CELL = 0.25  # m, finest walkable-grid cell
GRID_MAX_CELLS = 250_000  # cell size grows to stay under this
NAV_CLEARANCE = 0.3  # m, distance maps keep this far from obstacles
ARRIVE_RADIUS = 0.5  # m, a goal is reached inside this
SLOW_RADIUS = 2.0  # m, arrive slowing radius
# Wander (Reynolds): a point on a circle ahead of the agent, jittered.
WANDER_DISTANCE = 2.0  # m
WANDER_RADIUS = 1.0  # m
WANDER_RATE = 1.5  # rad / sqrt(s), random walk of the wander angle
WANDER_SPEED_FACTOR = 0.6
GRAZE_SPEED_FACTOR = 0.15  # herbivores drift slowly while eating

# --- interest fields (seed 003) -------------------------------------------
INTEREST_MIN = 0.05  # below this an exhibit no longer attracts
BETA_MIN = 0.05  # lower bound of the visibility / prior-knowledge factor
# Visiting profiles: (initial interest scale low, high, decay multiplier).
PROFILE_INTEREST = {"detailed": (1.0, 1.0, 0.5), "casual": (0.3, 1.0, 2.0),
                    "timeLimited": (0.8, 1.0, 1.0)}
LOOK_AT_RANGE = 3.0  # multiples of an exhibit's radius within which people look at it

# --- behavior maps (seed 004) ---------------------------------------------
ALARM_FACTOR = 4.0  # agents within this many radii of a blast react to it
ALARM_MIN = 30.0  # m, ...and at least this close
SAFE_FACTOR = 2.5  # fleeing stops beyond this many radii
VOLCANO_SPREAD_TIME = 20.0  # s for the volcano's damage to reach its radius
DEAD_DAMAGE = (0.5, 0.9)  # damage threshold for death, drawn per agent in range
WOUND_DAMAGE = (0.05, 0.3)  # damage threshold for wounds, drawn per agent
LINE_SPACING = 1.5  # m between security officers in a protective line
LINE_OFFSET = 1.15  # line distance from a threat, in its radii
PURSUIT_RANGE = 40.0  # m, security pursue attackers closer than this
THREAT_RANGE = 15.0  # m, attackers / herbivores evade pursuers closer than this
FOOD_PATCHES = 5  # patches of a generated food layer
FOOD_PATCH_RADIUS = 3.0  # m
MAP_THRESHOLD = 0.5  # a food / rest / forbidden cell counts above this value

# --- paths (seed 004) -----------------------------------------------------
# Obstacle size over character height above which the gradient map is used
# instead of Bezier curves (the seed: "different thresholds for different
# characters"). Birds fly over everything: infinite threshold.
GRADIENT_SIZE_RATIO = (3.0, 2.0, 20.0, np.inf)
STEEP_SLOPE = 0.3  # rise/run that makes a height-field region an "obstacle"
BEZIER_SPREAD = 0.2  # control points: lateral sigma as a fraction of the path length
BEZIER_SPREAD_MAX = 8.0  # m
BEZIER_LOOKAHEAD = 1.5  # m, carrot distance along the curve
SLOPE_LOOKAHEAD = 1.0  # m, where the next step's slope is estimated
SLOPE_PROBES = 12  # random directions tried when the way is too steep
DETOUR_TIME = 1.5  # s a chosen detour direction is kept

# --- animation (fallback only; usdcrowd.character.animation is preferred) --
IDLE_SPEED = 0.15  # m/s
RUN_SPEED = 2.4  # m/s

# Market trading (crowd:trades; seed 000's Weld Quay residents).
TRADE_NOTICE = 5.0  # m: a trading wanderer goes to a seller this close
TRADE_DISTANCE = 1.2  # m: and stops this far from them
TRADE_SECONDS = (4.0, 8.0)  # s: how long a trade lasts once face to face, drawn uniformly
TRADE_APPROACH = 6.0  # s: a buyer who has not reached the seller by then gives up
TRADE_COOLDOWN = 20.0  # s: before either trades again
