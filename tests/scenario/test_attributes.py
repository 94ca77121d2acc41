"""Attribute resolution down the group hierarchy, with seeded random defaults (seed 004)."""

from __future__ import annotations

import numpy as np
import pytest

from usdcrowd.core import model
from usdcrowd.core.errors import ScenarioError
from usdcrowd.scenario import load_scenario

TREE = '''
def Xform "World"
{
    def CrowdGroup "Parent"
    {
        uniform token crowd:personality = "security"
        uniform float2 crowd:speedRange = (2.0, 2.0)
        uniform color3f crowd:color = (0.1, 0.2, 0.3)

        def CrowdGroup "Child"
        {
            uniform token crowd:behavior = "run"
            uniform int crowd:clones = 6
            uniform int crowd:subclones = 3

            def SkelRoot "Override" (prepend apiSchemas = ["CrowdAgentAPI"])
            {
                uniform token crowd:personality = "attacker"
                uniform float crowd:speed = 3.5
            }
            def SkelRoot "AskForDraw" (prepend apiSchemas = ["CrowdAgentAPI"])
            {
                uniform token crowd:personality = "random"
            }
        }
    }
    def CrowdGroup "Other"
    {
        uniform int crowd:clones = 40
    }
}
'''


def _row(sc, suffix):
    return next(i for i, p in enumerate(sc.agents.path) if p.endswith(suffix))


def test_group_values_flow_down_and_agents_override(write_stage):
    sc = load_scenario(write_stage(TREE), seed=1)
    a = sc.agents
    clone = _row(sc, "Child/clone_0000")
    assert model.PERSONALITIES[a.personality[clone]] == "security"        # from the grandparent
    assert model.BEHAVIORS[a.behavior[clone]] == "run"                    # from the parent
    assert a.speed[clone] == pytest.approx(2.0)                           # range (2, 2)
    assert np.allclose(a.color[clone], (0.1, 0.2, 0.3), atol=1e-6)
    override = _row(sc, "Override")
    assert model.PERSONALITIES[a.personality[override]] == "attacker"
    assert a.speed[override] == pytest.approx(3.5)
    assert model.BEHAVIORS[a.behavior[override]] == "run"


def test_random_token_draws_from_the_documented_distribution(write_stage):
    # 'random' under a group that authors 'security' still draws: civilian 0.85 / security 0.15.
    counts = np.zeros(len(model.PERSONALITIES))
    path = write_stage(TREE)
    for seed in range(200):
        sc = load_scenario(path, seed=seed)
        counts[sc.agents.personality[_row(sc, "AskForDraw")]] += 1
    share = counts[model.PERSONALITIES.index("civilian")] / counts.sum()
    assert 0.75 < share < 0.95
    assert counts[model.PERSONALITIES.index("civilian")] + counts[model.PERSONALITIES.index("security")] == 200


def test_unset_values_are_drawn_and_vary_across_agents(write_stage):
    sc = load_scenario(write_stage(TREE), seed=5)
    other = [i for i, p in enumerate(sc.agents.path) if "/Other/" in p]
    a = sc.agents
    assert len(other) == 40
    assert len(np.unique(a.speed[other])) > 30                 # drawn in the fallback range
    assert a.speed[other].min() >= 1.1 and a.speed[other].max() <= 1.5
    assert len({tuple(c) for c in a.color[other]}) > 3         # palette draws
    assert set(a.condition[other]) == {0, 1}                   # grouped and isolated both drawn


def test_same_seed_same_table_other_seed_differs(write_stage):
    path = write_stage(TREE)
    a1, a2, b = (load_scenario(path, seed=s).agents for s in (11, 11, 12))
    for name in ("speed", "height", "color", "start", "personality", "behavior"):
        assert np.array_equal(getattr(a1, name), getattr(a2, name)), name
    assert not np.array_equal(a1.speed, b.speed)


def test_editing_one_group_leaves_the_others_draws_unchanged(write_stage):
    before = load_scenario(write_stage(TREE), seed=3)
    after = load_scenario(write_stage(TREE.replace("crowd:clones = 6", "crowd:clones = 9")), seed=3)
    rows_b = [i for i, p in enumerate(before.agents.path) if "/Other/" in p]
    rows_a = [i for i, p in enumerate(after.agents.path) if "/Other/" in p]
    assert np.array_equal(before.agents.speed[rows_b], after.agents.speed[rows_a])
    assert np.array_equal(before.agents.start[rows_b], after.agents.start[rows_a])


def test_subclones_share_their_drawn_attributes(write_stage):
    sc = load_scenario(write_stage(TREE.replace('uniform float2 crowd:speedRange = (2.0, 2.0)', '')), seed=2)
    rows = [_row(sc, f"Child/clone_{k:04d}") for k in range(6)]
    speeds = sc.agents.speed[rows]
    assert speeds[0] == speeds[1] == speeds[2] and speeds[3] == speeds[4] == speeds[5]
    assert speeds[0] != speeds[3]
    # Positions are per agent even within a run of subclones.
    assert len({tuple(p) for p in sc.agents.start[rows]}) == 6


def test_ids_are_unique_and_follow_authored_ones(museum_path):
    a = load_scenario(museum_path).agents
    assert len(np.unique(a.agent_id)) == len(a)
    teacher = next(i for i, p in enumerate(a.path) if p.endswith("Teacher"))
    assert a.agent_id[teacher] == 100 and a.agent_id.min() == 100


def test_leaders_are_resolved_from_roles(museum_path):
    sc = load_scenario(museum_path)
    a = sc.agents
    guide = next(i for i, p in enumerate(a.path) if p.endswith("Guide"))
    family = [i for i, p in enumerate(a.path) if "/Family/clone_" in p]
    assert model.ROLES[a.role[guide]] == "invisibleLeader" and not a.visible[guide]
    assert set(a.leader[family]) == {guide}


@pytest.mark.parametrize("edit, attribute", [
    ("uniform float2 crowd:speedRange = (2.0, 2.0)", "crowd:speedRange"),
    ("uniform int crowd:subclones = 3", "crowd:subclones"),
    ("uniform float crowd:speed = 3.5", "crowd:speed"),
])
def test_bad_values_name_file_prim_and_attribute(write_stage, edit, attribute):
    bad = {"crowd:speedRange": "uniform float2 crowd:speedRange = (-1.0, 2.0)",
           "crowd:subclones": "uniform int crowd:subclones = 0",
           "crowd:speed": "uniform float crowd:speed = -3.5"}[attribute]
    path = write_stage(TREE.replace(edit, bad))
    with pytest.raises(ScenarioError) as err:
        load_scenario(path)
    text = str(err.value)
    assert str(path) in text and attribute in text and "/World/" in text and "\n" not in text


def test_empty_group_is_an_error(write_stage):
    path = write_stage('def CrowdGroup "Nobody"\n{\n}\n')
    with pytest.raises(ScenarioError, match=r"Nobody.*empty group"):
        load_scenario(path)


@pytest.mark.parametrize("mode, top", [("I;16", 65535), ("I", 65535), ("L", 255)])
def test_painted_layers_are_normalised_by_the_image_mode(write_stage, tmp_path, mode, top):
    from PIL import Image

    pixels = np.array([[0, top], [top // 2, top]], dtype=np.int32)
    img = (Image.fromarray(pixels.astype(np.uint16)) if mode == "I;16"
           else Image.fromarray(pixels.astype(np.int32 if mode == "I" else np.uint8), mode))
    assert img.mode == mode
    img.save(tmp_path / "h.png" if mode != "I" else tmp_path / "h.tif")
    name = "h.png" if mode != "I" else "h.tif"
    path = write_stage(f'''
def CrowdGroup "G"
{{
    uniform int crowd:clones = 1
}}
def BehaviorLayer "Height"
{{
    uniform asset crowd:image = @{name}@
    uniform token crowd:meaning = "height"
    uniform float2 crowd:valueRange = (0, 40)
}}
''')
    values = load_scenario(path).field("height").values
    assert values.max() == pytest.approx(40.0) and values.min() == pytest.approx(0.0)
    assert values[1, 0] == pytest.approx(20.0, abs=0.2)


SCENERY = '''
def CrowdGroup "G"
{
    uniform int crowd:clones = 1
}
def Cylinder "Fountain"
{
    double radius = 1.5
    double height = 1
    double3 xformOp:translate = (4, 0, 0.5)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
def Mesh "Terrain" (prepend apiSchemas = ["CrowdSceneryAPI"])
{
    uniform token crowd:scenery = "ground"
    int[] faceVertexCounts = [4]
    int[] faceVertexIndices = [0, 1, 2, 3]
    point3f[] points = [(-20, -10, 0), (20, -10, 3), (20, 10, 3), (-20, 10, 0)]
}
def Xform "Decor" (prepend apiSchemas = ["CrowdSceneryAPI"])
{
    uniform token crowd:scenery = "ignore"
    def Cube "Statue"
    {
        double size = 2
    }
}
def Plane "Rope" (prepend apiSchemas = ["CrowdSceneryAPI"])
{
    uniform token crowd:scenery = "obstacle"
    double width = 4
    double length = 0.2
    double3 xformOp:translate = (-5, 0, 0)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
'''


def test_scenery_roles_and_round_footprints(write_stage):
    sc = load_scenario(write_stage(SCENERY))
    obstacles = dict(zip(sc.obstacles.path, sc.obstacles.polygons))
    assert set(obstacles) == {"/Fountain", "/Rope"}          # terrain is ground, decor ignored
    fountain = obstacles["/Fountain"]
    radius = np.linalg.norm(fountain - (4, 0), axis=1)
    assert len(fountain) >= 16 and np.allclose(radius, 1.5, atol=1e-3)      # round, not a 3 m square
    assert np.allclose(sc.bounds, [[-20, -10], [20, 10]])                    # the tagged terrain sets the bounds
