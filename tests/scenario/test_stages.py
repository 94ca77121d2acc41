"""The example stages in stages/: each loads, validates, has the crowd it is
meant to have, reads its painted maps with their value ranges, and survives
being copied as a template (``usdcrowd new``)."""

from __future__ import annotations

import functools
import importlib.util
from pathlib import Path

import numpy as np

from usdcrowd.core.errors import UsdcrowdError
import pytest
from PIL import Image

from usdcrowd.core import model
from usdcrowd.core.resources import data_dir
from usdcrowd.scenario import load_scenario
from usdcrowd.jobs.templates import new_scenario
from usdcrowd.jobs.validation import validate

STAGES = sorted(data_dir("stages").glob("*.usda"))
NAMES = [p.stem for p in STAGES]

# Agents per group (groups with direct members, paths under /World/Crowd/).
# Stages not listed here only need some agents.
EXPECTED_AGENTS = {
    "volcano": {"Civilians/Villagers": 28, "Civilians/Market": 12, "Civilians/Farmers": 8,
                "Civilians/Elders": 4, "Security": 8},
    "explosion": {"Civilians/Strollers": 22, "Civilians/Shoppers": 20, "Civilians/Cafe": 12,
                  "Civilians/Families": 10, "Security/Patrol": 6, "Security/Posts": 6, "Attackers": 4},
    "animals": {"Herd": 21, "Ants": 120, "Birds": 16},
    "harbour": {"Residents/Sellers": 12, "Residents/Shoppers": 36, "Townsfolk": 30,
                "Workers/GangMarket": 16, "Workers/GangGodown": 16},
    "dialogue": {"Pair": 2, "Walkers/Left": 1, "Walkers/Right": 1},
}

# Behavior layers: (meaning, generator, image or None, value range of a painted one).
EXPECTED_LAYERS = {
    "volcano": {"Height": ("height", "painted", "maps/volcano_height.png", (0.0, 40.0)),
                "Eruption": ("damage", "volcano", None, None)},
    "explosion": {"Blast": ("damage", "explosion", None, None)},
    "animals": {"Food": ("food", "painted", "maps/animals_food.png", (0.0, 1.0)),
                "Rest": ("rest", "painted", "maps/animals_rest.png", (0.0, 1.0))},
    "harbour": {"Water": ("forbidden", "painted", "maps/harbour_water.png", (0.0, 1.0))},
    "dialogue": {},
}


@functools.lru_cache(maxsize=None)
def _scenario(name: str) -> model.Scenario:
    return load_scenario(data_dir("stages") / f"{name}.usda")


def _crowd_counts(sc: model.Scenario) -> dict[str, int]:
    counts = np.bincount(np.asarray(sc.agents.group), minlength=len(sc.groups.path))
    return {p.split("/Crowd/", 1)[-1]: int(c) for p, c in zip(sc.groups.path, counts) if c}


def _layers(sc: model.Scenario) -> dict[str, model.BehaviorField]:
    return {f.path.rsplit("/", 1)[-1]: f for f in sc.fields}


def _codes(table, name, vocab) -> set[str]:
    return {vocab[int(c)] for c in np.asarray(getattr(table, name))}


def test_the_example_stages_are_all_there():
    assert {"museum", *EXPECTED_AGENTS} <= set(NAMES)


@pytest.mark.parametrize("name", NAMES)
def test_stage_loads_and_validates_without_errors(name):
    sc = _scenario(name)
    assert len(sc.agents) > 0
    errors = [str(p) for p in validate(data_dir("stages") / f"{name}.usda") if p.severity == "error"]
    assert errors == []


def test_every_stages_sun_is_normalised_and_validate_warns_of_one_that_is_not(tmp_path):
    """UsdLux: an unnormalised DistantLight's intensity is its disc's luminance, so a 0.53-degree sun of
    intensity 3 would light nothing (Blender renders it so). Every example sun is normalised; validate warns,
    naming the attribute, about one that is not."""
    from pxr import Usd, UsdLux

    for name in NAMES:
        path = data_dir("stages") / f"{name}.usda"
        stage = Usd.Stage.Open(str(path))
        suns = [p for p in stage.Traverse() if p.IsA(UsdLux.DistantLight)]
        assert suns and all(UsdLux.DistantLight(p).GetNormalizeAttr().Get() for p in suns), name
        assert not [p for p in validate(path) if p.attribute == "inputs:normalize"]
    old = tmp_path / "old_museum.usda"
    old.write_text((data_dir("stages") / "museum.usda").read_text().replace("bool inputs:normalize = true", ""))
    warned = [p for p in validate(old) if p.attribute == "inputs:normalize"]
    assert [(p.prim, p.severity) for p in warned] == [("/World/Lights/Sun", "warning")]
    assert "6.7e-05" in warned[0].message


@pytest.mark.parametrize("name", NAMES)
def test_agent_counts_are_as_intended(name):
    sc = _scenario(name)
    counts = _crowd_counts(sc)
    assert all(c > 0 for c in counts.values()) and sum(counts.values()) == len(sc.agents)
    if name in EXPECTED_AGENTS:
        assert counts == EXPECTED_AGENTS[name]


@pytest.mark.parametrize("name", NAMES)
def test_painted_layers_load_with_their_value_ranges(name):
    from pxr import Usd

    stage = Usd.Stage.Open(str(data_dir("stages") / f"{name}.usda"))
    fields = _layers(_scenario(name))
    for prim in stage.Traverse():
        if prim.GetTypeName() != "BehaviorLayer":
            continue
        f = fields[prim.GetName()]
        if model.LAYER_GENERATORS[f.generator] != "painted":
            assert f.values is None
            continue
        lo, hi = prim.GetAttribute("crowd:valueRange").Get()
        # Every map spans its dtype's full range, so the layer spans valueRange.
        assert f.values.min() == pytest.approx(lo, abs=1e-4)
        assert f.values.max() == pytest.approx(hi, rel=1e-5)
    if name in EXPECTED_LAYERS:
        want = EXPECTED_LAYERS[name]
        assert set(fields) == set(want)
        for layer, (meaning, generator, image, vrange) in want.items():
            f = fields[layer]
            assert (model.LAYER_MEANINGS[f.meaning], model.LAYER_GENERATORS[f.generator]) == (meaning, generator)
            if image is not None:
                assert (data_dir("stages") / image).is_file()
                assert (float(f.values.min()), float(f.values.max())) == pytest.approx(vrange, abs=1e-4)


def test_volcano_height_map_is_16_bit_and_the_others_8_bit():
    maps = data_dir("stages") / "maps"
    with Image.open(maps / "volcano_height.png") as im:
        assert im.mode == "I;16" and im.size == (256, 256)
    for other in ("animals_food.png", "animals_rest.png", "harbour_water.png"):
        with Image.open(maps / other) as im:
            assert im.mode == "L" and im.size == (256, 256)


def test_volcano_terrain_and_slopes():
    sc = _scenario("volcano")
    height = sc.field("height")
    # The village stands on the flat plain (scenery bottoms are at z = 0);
    # the crater is a dip in the top of the cone.
    village, crater, rim = height.sample(np.array([[-36.0, -30.0], [35.0, 35.0], [35.0, 41.0]]))
    assert village == pytest.approx(0.0, abs=0.1)
    assert crater < rim and rim > 35.0
    # Groups author different slope limits, so the terrain stops some and not others.
    assert len(np.unique(np.round(sc.agents.max_slope, 3))) >= 3
    pers = np.array([model.PERSONALITIES[c] for c in sc.agents.personality])
    fear = np.array([model.FEAR_RESPONSES[c] for c in sc.agents.fear_response])
    assert set(fear[pers == "civilian"]) == {"flee", "freeze"}     # fearResponse random: a mix
    assert (pers == "security").sum() == 8
    eruption = _layers(sc)["Eruption"]
    assert eruption.start_time == 48 and eruption.radius > 0


def test_explosion_personalities():
    sc = _scenario("explosion")
    a = sc.agents
    pers = np.array([model.PERSONALITIES[c] for c in a.personality])
    assert (pers == "attacker").sum() == 4 and (pers == "security").sum() == 12
    fear = np.array([model.FEAR_RESPONSES[c] for c in a.fear_response])
    assert set(fear[pers == "civilian"]) == {"flee", "freeze"}
    blast = _layers(sc)["Blast"]
    assert blast.radius == pytest.approx(8.0) and blast.start_time == 60


def test_animal_kinds():
    sc = _scenario("animals")
    kinds = np.array([model.CHARACTER_TYPES[c] for c in sc.agents.character_type])
    behaviors = np.array([model.BEHAVIORS[c] for c in sc.agents.behavior])
    assert set(behaviors[kinds == "herbivore"]) == {"graze"}
    assert set(behaviors[kinds == "bird"]) == {"flock"}
    assert (kinds == "ant").sum() >= 100
    ants = sc.agents.start[kinds == "ant", :2]
    assert np.linalg.norm(ants - ants.mean(0), axis=1).max() <= 1.5 + 1e-6
    # Some food lies within reach of the ant hill, and none under it.
    food = sc.field("food")
    assert food.sample(np.array([[-30.0, -30.0]]))[0] < 0.5
    xs, ys = np.meshgrid(np.linspace(-40, -20, 41), np.linspace(-40, -20, 41))
    assert food.sample(np.stack([xs.ravel(), ys.ravel()], 1)).max() > 0.9


def test_harbour_workers_cameras_and_boat():
    from pxr import Usd, UsdGeom

    sc = _scenario("harbour")
    roles = _codes(sc.agents, "role", model.ROLES)
    assert {"leader", "invisibleLeader"} <= roles
    # The water is forbidden, the pier (the workers' goal) is not.
    water = sc.field("forbidden")
    goal = sc.groups.goal[sc.groups.path.index("/World/Crowd/Workers")]
    assert water.sample(np.array([goal[:2], [-20.0, 20.0], [-20.0, -20.0]])).tolist() == [0.0, 1.0, 0.0]

    stage = Usd.Stage.Open(str(data_dir("stages") / "harbour.usda"))
    agents = [p for p in stage.Traverse() if p.HasAPI("CameraAgentAPI")]
    assert len(agents) >= 3
    modes = {str(p.GetAttribute("crowd:camera:mode").Get()) for p in agents}
    assert modes == {"scouting", "tracking"}
    # The boat reaches the pier around frame 60 and is still there at 480.
    boat = UsdGeom.Xformable(stage.GetPrimAtPath("/World/Scenery/Boat"))
    at = {t: np.array(boat.ComputeLocalToWorldTransform(t))[3, :2] for t in (1, 60, 480, 900)}
    assert np.linalg.norm(at[60] - [14.6, 16.0]) < 0.5 and np.allclose(at[60], at[480])
    assert np.linalg.norm(at[1] - at[60]) > 20 and np.linalg.norm(at[900] - at[60]) > 20
    # The workers go to the pier, then back to the godowns (a time-sampled goal).
    times, points = sc.groups.waypoints[sc.groups.path.index("/World/Crowd/Workers")]
    assert times.tolist() == [1.0, 330.0] and water.sample(points[:, :2]).tolist() == [0.0, 0.0]


def test_dialogue_configuration():
    from pxr import Usd

    sc = _scenario("dialogue")
    a = sc.agents
    row = {p.rsplit("/", 1)[-1]: i for i, p in enumerate(a.path)}
    pa, pb = a.start[row["A"], :2], a.start[row["B"], :2]
    assert np.linalg.norm(pb - pa) == pytest.approx(1.5)
    to_b = np.arctan2(*(pb - pa)[::-1])
    assert np.cos(a.start_heading[row["A"]] - to_b) == pytest.approx(1.0, abs=1e-6)       # A faces B
    assert np.cos(a.start_heading[row["B"]] - to_b) == pytest.approx(-1.0, abs=1e-6)      # B faces A
    # The walkers start abreast (side by side across their common direction).
    pc, pd = a.start[row["C"], :2], a.start[row["D"], :2]
    gc = sc.groups.goal[a.group[row["C"]], :2]
    gd = sc.groups.goal[a.group[row["D"]], :2]
    assert np.allclose(gc - pc, gd - pd) and abs(np.dot(pc - pd, gc - pc)) < 1e-6
    assert a.speed[row["C"]] == a.speed[row["D"]]

    stage = Usd.Stage.Open(str(data_dir("stages") / "dialogue.usda"))
    event = stage.GetPrimAtPath("/World/Events/Dialogue")
    assert event.GetAttribute("crowd:kind").Get() == "dialogue"
    assert [str(t) for t in event.GetRelationship("crowd:members").GetTargets()] == \
        ["/World/Crowd/Pair/A", "/World/Crowd/Pair/B"]
    cams = [p for p in stage.Traverse() if p.GetTypeName() == "Camera"]
    assert len(cams) == 1


@pytest.mark.parametrize("name", NAMES)
def test_template_copy_keeps_its_images_and_loads(name, tmp_path):
    original = _scenario(name)
    n = 2 * len(original.agents)
    out = tmp_path / "x.usda"
    try:
        result = new_scenario(name, out, agents=n)
    except UsdcrowdError as exc:            # a template with no clones keeps its cast
        assert "fixed cast" in str(exc)
        n = len(original.agents)
        result = new_scenario(name, out, agents=n)
    assert result["agents"] == n
    for asset in result["assets"]:
        assert Path(asset).is_file() and Path(asset).parent.parent == tmp_path
    sc = load_scenario(out)
    assert len(sc.agents) == n
    before, after = _layers(original), _layers(sc)
    assert set(before) == set(after)
    for layer, f in before.items():
        if f.values is not None:
            np.testing.assert_array_equal(after[layer].values, f.values)


def test_maps_are_what_the_script_makes(tmp_path):
    script = data_dir("stages").parent / "tools" / "make_stage_maps.py"
    if not script.is_file():
        pytest.skip("tools/ is not shipped with an installed package")
    spec = importlib.util.spec_from_file_location("make_stage_maps", script)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert mod.main(["--out", str(tmp_path)]) == 0
    for png in sorted(tmp_path.glob("*.png")):
        with Image.open(png) as made, Image.open(data_dir("stages") / "maps" / png.name) as kept:
            assert made.mode == kept.mode
            np.testing.assert_array_equal(np.asarray(made), np.asarray(kept))
