"""Behavior maps, reactions by attributes, and paths (seed 004)."""

from __future__ import annotations

import numpy as np

import tests.helpers.scenarios as S
from usdcrowd.core.model import BEHAVIORS, HEALTH_STATES, PATH_METHODS
from usdcrowd.sim import simulate
from usdcrowd.sim import params as P
from usdcrowd.sim.behavior_maps import MapLayer
from usdcrowd.sim.paths import Terrain, choose_path_method, slope_map

RUN, REST, GRAZE = (BEHAVIORS.index(b) for b in ("run", "rest", "graze"))
WIDE = ((-30, -30), (30, 30))


def explosion_scene(frames=240, seed=1):
    rng = np.random.default_rng(seed)
    n = 40
    start = rng.uniform(-12, 12, (n, 2))
    start[0] = (2.5, 1.0)  # right at the blast
    pers = ["civilian"] * 30 + ["security"] * 6 + ["attacker"] * 4
    fear = ["flee"] * 24 + ["freeze"] * 16
    at = S.agents(start, personality=pers, fear=fear, behavior="wander", condition="isolated")
    blast = S.field("damage", "explosion", origin=(2, 1, 0), radius=6.0, start_time=24.0, extent=WIDE)
    return S.scenario(at, S.groups([[np.nan] * 3]), fields=[blast], frames=frames, bounds=WIDE, seed=seed)


def test_explosion_civilians_flee_freeze_and_get_hurt():
    sc = explosion_scene()
    fr = simulate(sc)
    o = np.array([2.0, 1.0])
    d = np.linalg.norm(fr.position[:, :, :2] - o, axis=2)
    fleers, freezers = np.arange(1, 24), np.arange(24, 30)
    blast = 23  # frame index of time code 24
    # Fleeing civilians get away: mean distance to the origin grows.
    assert d[-1, fleers].mean() > d[blast, fleers].mean() + 5.0
    assert np.all(np.diff(d[blast::24, fleers].mean(axis=1)) > 0)
    # Paralysed ones stay put (jostled at most at the resting speed cap).
    sp = np.linalg.norm(fr.velocity[blast + 36:, freezers], axis=2)
    assert sp.max() <= P.REST_SPEED_MAX + 1e-4
    assert np.all(fr.behavior[-1, freezers] == REST)
    # The one at the blast is wounded or dead; health never improves.
    assert fr.health[-1, 0] >= HEALTH_STATES.index("wounded")
    assert np.all(np.diff(fr.health.astype(int), axis=0) >= 0)
    assert np.all(fr.health[:blast] == 0)
    # They look at the blast once it happened, not before.
    assert np.all(np.isnan(fr.look_at[:blast, fleers]))
    near = fleers[d[-1, fleers] < 30]
    np.testing.assert_allclose(fr.look_at[-1, near, :2], np.broadcast_to(o, (near.size, 2)), atol=1e-5)


def test_security_pursues_attackers_who_flee():
    sc = explosion_scene(frames=120)
    fr = simulate(sc)
    sec, att = np.arange(30, 36), np.arange(36, 40)
    assert np.all(fr.behavior[-1, sec] == RUN) and np.all(fr.behavior[-1, att] == RUN)
    # Officers look at (their) attacker (as it was at the last step: < 0.2 m).
    looks = fr.look_at[-1, sec, :2]
    dist = np.linalg.norm(looks[:, None, :] - fr.position[-1, att][None, :, :2], axis=2)
    assert np.all(dist.min(axis=1) < 0.2)


def test_security_forms_a_line_without_attackers():
    rng = np.random.default_rng(4)
    civ = rng.uniform(5, 15, (20, 2))
    sec = np.stack([np.linspace(-10, 10, 5), np.full(5, -12.0)], axis=1)
    at = S.agents(np.concatenate([civ, sec]), personality=["civilian"] * 20 + ["security"] * 5,
                  behavior="rest", condition="isolated")
    volcano = S.field("damage", "volcano", origin=(0, 0, 0), radius=5.0, start_time=1.0, extent=WIDE)
    fr = simulate(S.scenario(at, S.groups([[np.nan] * 3]), fields=[volcano], frames=360, bounds=WIDE))
    p = fr.position[-1, 20:, :2].astype(float)
    # Officers stand on a line at LINE_OFFSET radii from the crater, facing it.
    r = np.linalg.norm(p, axis=1)
    assert np.all(np.abs(r - 5.0 * P.LINE_OFFSET) < 3.0)
    centred = p - p.mean(axis=0)
    sv = np.linalg.svd(centred, compute_uv=False)
    assert sv[1] < 0.25 * sv[0]  # nearly collinear
    np.testing.assert_allclose(fr.look_at[-1, 20:, :2], 0.0, atol=1e-5)


def test_herbivores_find_food_and_graze():
    rng = np.random.default_rng(2)
    at = S.agents(rng.uniform(-25, -15, (12, 2)), character="herbivore", personality="herbivore",
                  behavior="graze", speed=1.5, height=1.4, condition="isolated")
    food = S.field("food", "food", origin=(10, 10, 0), radius=4.0, extent=WIDE)
    sc = S.scenario(at, S.groups([[np.nan] * 3]), fields=[food], frames=720, bounds=WIDE)
    fr = simulate(sc)
    layer = MapLayer(food, lambda tc: tc - 1.0, np.random.default_rng(0))
    # The sim draws patches from its own stream; check against its layer.
    from usdcrowd.sim import Simulation
    sim_layer = Simulation(sc).reactions.food[0]
    v = sim_layer.sample(fr.position[-1, :, 0], fr.position[-1, :, 1], 1e9)
    assert np.mean(v > P.MAP_THRESHOLD) >= 0.75
    assert np.mean(fr.behavior[-1] == GRAZE) >= 0.75
    assert layer.render(0.0).shape == (128, 128)


def test_herbivore_evades_predator():
    at = S.agents([[0, 0], [-6, 0]], character=["herbivore", "herbivore"], personality=["herbivore", "predator"],
                  behavior="wander", speed=[1.5, 1.0], height=1.4, condition="isolated")
    fr = simulate(S.scenario(at, S.groups([[np.nan] * 3]), frames=96, bounds=WIDE))
    d = np.linalg.norm(fr.position[:, 0, :2] - fr.position[:, 1, :2], axis=1)
    assert d[-1] > d[0]
    assert fr.behavior[-1, 0] == RUN


def test_forbidden_area_is_never_entered():
    img = np.zeros((40, 40), np.float32)
    img[14:26, 18:22] = 1.0  # a painted forbidden strip across the middle (x in +-2, y in +-6 m)
    forb = S.field("forbidden", values=img)
    at = S.agents(np.stack([np.full(10, -12.0), np.linspace(-5, 5, 10)], axis=1), condition="isolated")
    sc = S.scenario(at, S.groups([[12, 0, 0]]), fields=[forb], frames=600)
    fr = simulate(sc)
    v = forb.sample(fr.position[:, :, :2].reshape(-1, 2))
    assert np.all(v == 0)
    assert np.median(fr.position[-1, :, 0]) > 5.0  # they went around


def ridge_terrain():
    """A 4 m high ridge along x = 0 with a gentle pass at y = 10."""
    xs = np.linspace(-19.75, 19.75, 80)
    X, Y = np.meshgrid(xs, xs[::-1])  # row 0 = +Y
    h = 4.0 * np.exp(-X ** 2 / (2 * 2.0 ** 2)) * (1 - 0.95 * np.exp(-(Y - 10) ** 2 / (2 * 3.0 ** 2)))
    return S.field("height", values=h)


def test_slope_limited_agents_never_step_onto_too_steep_ground():
    height = ridge_terrain()
    at = S.agents(np.stack([np.full(8, -12.0), np.linspace(-4, 4, 8)], axis=1), max_slope=0.3,
                  condition="isolated")
    sc = S.scenario(at, S.groups([[12, 0, 0]]), fields=[height], frames=480)
    fr = simulate(sc)
    assert np.all(fr.path_method == PATH_METHODS.index("gradient"))
    t = Terrain(height)
    p = fr.position[:, :, :2].reshape(-1, 2)
    s = t.slope(p[:, 0], p[:, 1])
    assert s.max() <= 0.3
    assert slope_map(height).max() > 0.9  # the ridge really is steeper than the limit
    # z follows the ground.
    np.testing.assert_allclose(fr.position[..., 2].ravel(), t.height(p[:, 0], p[:, 1]), atol=1e-5)
    # A goat-like agent (max slope 2) walks straight over the ridge.
    at2 = S.agents([[-12.0, 0.0]], max_slope=2.0)
    fr2 = simulate(S.scenario(at2, S.groups([[12, 0, 0]]), fields=[height], frames=480))
    assert fr2.position[-1, 0, 0] > 8.0 and np.abs(fr2.position[:, 0, 1]).max() < 1.5


def test_path_method_rule_and_bezier_variety():
    at = S.agents(np.stack([np.full(6, -15.0), np.linspace(-1, 1, 6)], axis=1), condition="isolated")
    g = S.groups([[15, 0, 0]])
    assert np.all(choose_path_method(S.scenario(at, g), Terrain(None)) == PATH_METHODS.index("direct"))
    pillars = [S.box(x, y, 0.3, 0.3) for x in (-5, 0, 5) for y in (-4, 0, 4)]
    sc = S.scenario(at, g, obstacles=pillars, frames=720)
    fr = simulate(sc)
    assert np.all(fr.path_method == PATH_METHODS.index("bezier"))
    # Each agent follows its own curve: lateral spread grows along the way,
    # and they still arrive.
    assert np.ptp(fr.position[120, :, 1]) > np.ptp(fr.position[0, :, 1]) + 1.0
    assert np.all(np.linalg.norm(fr.position[-1, :, :2] - [15, 0], axis=1) < 4.0)
    wall = S.scenario(at, g, obstacles=[S.box(0, 0, 0.5, 10.0)])
    assert np.all(choose_path_method(wall, Terrain(None)) == PATH_METHODS.index("gradient"))
    birds = S.scenario(S.agents([[0, 0]], character="bird"), g, obstacles=[S.box(0, 0, 0.5, 10.0)])
    assert choose_path_method(birds, Terrain(None))[0] == PATH_METHODS.index("direct")


def test_birds_fly_above_ground():
    rng = np.random.default_rng(0)
    at = S.agents(rng.uniform(-5, 5, (10, 2)), character="bird", behavior="flock", speed=4.0, height=0.2)
    fr = simulate(S.scenario(at, S.groups([[np.nan] * 3]), frames=96))
    z = fr.position[48:, :, 2]
    assert np.all(z > 1.0) and np.all(z < P.BIRD_ALTITUDE[1] + 1e-3)


def test_a_huge_painted_map_is_read_at_the_resolution_the_simulation_uses(write_stage, tmp_path):
    """4000 x 4000 px over 20 m (5 mm a pixel) is read as 400 x 400 float32, painted values kept."""
    from PIL import Image

    from usdcrowd.scenario import load_scenario
    from usdcrowd.scenario.read import MAP_RESOLUTION

    mask = np.zeros((4000, 4000), np.uint8)
    mask[:, 2000:] = 255                                   # east half forbidden
    Image.fromarray(mask).save(tmp_path / "huge.png")
    stage = write_stage(f'''
def Xform "World"
{{
    def CrowdGroup "Crowd"
    {{
        uniform int crowd:clones = 2
    }}
    def BehaviorLayer "Mask"
    {{
        uniform token crowd:meaning = "forbidden"
        uniform asset crowd:image = @{tmp_path / "huge.png"}@
        uniform float2 crowd:extentMin = (-10, -10)
        uniform float2 crowd:extentMax = (10, 10)
        uniform float2 crowd:valueRange = (0, 1)
    }}
}}
''')
    field = load_scenario(stage).field("forbidden")
    assert field.values.shape == (round(20 / MAP_RESOLUTION),) * 2 and field.values.dtype == np.float32
    assert set(np.unique(field.values)) == {0.0, 1.0}
    np.testing.assert_array_equal(field.sample(np.array([[-5.0, 0.0], [5.0, 0.0]])), [0.0, 1.0])
