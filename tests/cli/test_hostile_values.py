"""Bad values in a scenario (issue 28): every one is a one-line error from `simulate` (exit 2, no shot) and
from `validate`, naming the file, the prim and the attribute, and `validate` reports them all in one run."""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
import pytest

from usdcrowd.cli import main

TEACHER = "uniform token crowd:role = \"leader\""           # the Students' leader (agent id 100)
GUIDE = "uniform token crowd:role = \"invisibleLeader\""    # the Family's leader
FAMILY = "uniform float crowd:spawnRadius = 1.5"            # on the Family group
EXHIBITS = 'def Scope "Exhibits"'                           # where new prims go, under /World
STATUE = r'(?<=def InterestPoint "Statue")(\s*\{[^}]*?)double3 xformOp:translate = \(-6, 3, 0\)'
LAMP = "float inputs:intensity = 200"
SKY = "float inputs:intensity = 0.6"


@dataclass
class Case:
    """A scenario edit (regex -> replacement, first match; ``count`` 0: every match) and what the error names."""

    id: str
    edits: list
    where: str                  # prim.attribute, or a stage attribute
    words: str                  # in the message
    files: dict | None = None   # name -> bytes or a (h, w) float32 array (a float TIFF) written beside the stage


def _layer(meaning="interest", image="map.tif", extra=""):
    return (f'def BehaviorLayer "Map"\n    {{\n        uniform token crowd:meaning = "{meaning}"\n'
            f'        uniform asset crowd:image = @./{image}@\n        uniform float2 crowd:extentMin = (-10, -10)\n'
            f'        uniform float2 crowd:extentMax = (10, 10)\n{extra}    }}\n    {EXHIBITS}')


def _texels(value):
    a = np.full((16, 16), 0.5, np.float32)
    a[5, 7] = value
    return a


def _edit(pattern, new, count=1):
    return (pattern, new, count)


def _set(name, pattern, new, where, words, files=None):
    """A case that replaces ``pattern``'s first match with ``new``."""
    return Case(name, [_edit(pattern, new)], where, words, files)


def _add(name, anchor, line, where, words, files=None):
    """A case that authors ``line`` after ``anchor`` (on the same prim)."""
    return _set(name, re.escape(anchor), f"{anchor}\n {line}", where, words, files)


def _family(name, pattern, line, values, where, words):
    """One case per value: ``pattern``'s first match replaced by ``line`` with the value in it."""
    return [Case(f"{name}-{value}", [_edit(pattern, line.format(value))], where, words) for value in values]


def _sphere(radius):
    return _edit(EXHIBITS, f'def Sphere "Ball"\n    {{\n        double radius = {radius}\n    }}\n    {EXHIBITS}')


_TEXELS = {"nan": np.nan, "inf": np.inf, "-inf": -np.inf}
_NOWHERE = "/World/Nowhere"
_STAND = ('def Xform "Stand" (\n        variants = {\n            string look = "gone"\n        }\n'
          '        prepend variantSets = "look"\n    )\n    {\n        variantSet "look" = {\n'
          '            "plain" {\n            }\n        }\n    }\n    ')
_TALK = ('def CrowdEvent "Talk"\n    {\n        uniform token crowd:kind = "dialogue"\n'
         f'        rel crowd:members = <{_NOWHERE}>\n        uniform double crowd:startTime = 1\n'
         '        uniform double crowd:endTime = 6\n    }\n    ')
_GUARDS_SPAWN = r"uniform float crowd:spawnRadius = 1\n"
_GUARDS_CENTRE = r"crowd:spawnCenter = \(0, 8, 0\)"

CASES = [
    # 1. float behavior-map textures
    *[_set(f"texel-{k}", EXHIBITS, _layer("height" if k == "-inf" else "interest"), "/World/Map.crowd:image",
           "not a finite number", {"map.tif": _texels(v)}) for k, v in _TEXELS.items()],
    _set("texels-times-range-overflow", EXHIBITS, _layer(extra="        uniform float2 crowd:valueRange = (0, 3e38)\n"),
         "/World/Map.crowd:valueRange", "not finite numbers", {"map.tif": _texels(1e6)}),
    _set("terrain-1e9-m-high", EXHIBITS, _layer("height", extra="        uniform float2 crowd:valueRange = (0, 1e9)\n"),
         "/World/Map.crowd:valueRange", "100 km", {"map.tif": _texels(1.0)}),
    _set("map-extent-1e30", EXHIBITS, _layer().replace("(10, 10)", "(1e30, 10)"), "/World/Map.crowd:extentMax",
         "100 km", {"map.tif": _texels(1.0)}),
    # 2. absurd sizes and speeds (heights are metres, whatever the stage's unit)
    *_family("height", r"uniform float crowd:height = [\d.]+", "uniform float crowd:height = {}",
             ["1e30", "25", "0.0001"], "Teacher.crowd:height", "heights are 0.001 to 10 m"),
    _add("height-range-1e30", FAMILY, "uniform float2 crowd:heightRange = (1.5, 1e30)", "Family.crowd:heightRange",
         "heights are 0.001 to 10 m"),
    _set("speed-range-1e30", r"crowd:speedRange = \(0.9, 1.3\)", "crowd:speedRange = (0.9, 1e30)",
         "Visitors.crowd:speedRange", "speeds are 0 to 50 m/s"),
    _add("speed-1e6", TEACHER, "uniform float crowd:speed = 1e6", "Teacher.crowd:speed", "speeds are 0 to 50 m/s"),
    # 3. ids that do not fit (the renderers' id buffers hold agent ids below 2^24)
    *_family("id", r"crowd:agentId = 100", "crowd:agentId = {}", ["2147483646", "0"], "Teacher.crowd:agentId",
             "agent ids are 1 to 16,777,215"),
    _set("id-clones-overflow", r"crowd:agentId = 100", "crowd:agentId = 16777214", "Teacher.crowd:agentId",
         "past the largest agent id 16,777,215"),
    # 4. frame rate
    *_family("fps", r"timeCodesPerSecond = 24", "timeCodesPerSecond = {}", ["0", "-24", "nan", "inf", "1e9"],
             "timeCodesPerSecond", "must be 1 to 1000"),
    # 5. units and axes
    *_family("mpu", r"metersPerUnit = 1", "metersPerUnit = {}", ["0", "-1", "1e-300", "1e30", "nan", "inf"],
             "metersPerUnit", "is not a unit"),
    *_family("up-axis", r'upAxis = "Z"', 'upAxis = "{}"', ["X", "z"], "upAxis", "is not an up axis"),
    # 6. leaders must lead somewhere
    _add("leader-follows-itself", TEACHER, "rel crowd:leader = </World/Crowd/Visitors/Students/Teacher>",
         "Teacher.crowd:leader", "follows itself"),
    Case("leaders-follow-each-other",
         [_edit(TEACHER, TEACHER + "\n rel crowd:leader = </World/Crowd/Visitors/Family/Guide>"),
          _edit(GUIDE, GUIDE + "\n rel crowd:leader = </World/Crowd/Visitors/Students/Teacher>")],
         "Guide.crowd:leader", "follow each other in a circle"),
    # 7. positions and lengths: finite, and within 100 km before any grid is allocated
    *_family("goal", FAMILY, FAMILY + "\n uniform point3f crowd:goal = {}", ["(nan, 0, 0)", "(0, -inf, 0)"],
             "Family.crowd:goal", "not a finite number"),
    _add("goal-1e30", FAMILY, "uniform point3f crowd:goal = (1e30, 0, 0)", "Family.crowd:goal", "within 100 km"),
    _add("goal-waypoint-nan", FAMILY, "point3f crowd:goal.timeSamples = {1: (0, 0, 0), 6: (nan, 0, 0)}",
         "Family.crowd:goal", "not a finite position"),
    _set("interest-nan", STATUE, r"\1double3 xformOp:translate = (nan, 3, 0)", "Statue.xformOp:translate",
         "not a finite value"),
    *_family("interest", STATUE, r"\1double3 xformOp:translate = {}", ["(1e30, 3, 0)", "(-6, 2e5, 0)"],
             "Statue.xformOp:translate", "within 100 km"),
    _set("interest-radius-inf", r"crowd:radius = 2.5", "crowd:radius = inf", "Statue.crowd:radius",
         "not a finite number"),
    _set("interest-radius-1e30", r"crowd:radius = 2.5", "crowd:radius = 1e30", "Statue.crowd:radius",
         "within 100 km"),
    *[Case(f"sphere-radius-{v}", [_sphere(v)], "/World/Ball.radius", "must be a finite number >= 0")
      for v in ("nan", "inf", "-1")],
    Case("sphere-radius-1e30", [_sphere("1e30")], "/World/Ball.radius", "within 100 km"),
    _set("cube-size-negative", r"double size = 1", "double size = -1", "WallNorth.size",
         "must be a finite number >= 0"),
    _set("wall-scale-1e30", r"xformOp:scale = \(30, 0.3, 3\)", "xformOp:scale = (1e30, 0.3, 3)",
         "WallNorth.xformOp:scale", "within 100 km"),
    _set("floor-points-1e30", r"points = \[\(-15, -10, 0\)", "points = [(-1e30, -10, 0)", "Floor.points",
         "within 100 km"),
    _set("agent-start-1e30", r"crowd:startPosition = \(-10, 6, 0\)", "crowd:startPosition = (1e30, 6, 0)",
         "Teacher.crowd:startPosition", "within 100 km"),
    _add("agent-transform-1e30", TEACHER, 'double3 xformOp:translate = (0, 1e30, 0)\n uniform token[] '
                                          'xformOpOrder = ["xformOp:translate"]',
         "Teacher.xformOp:translate", "within 100 km"),
    _set("spawn-center-1e30", _GUARDS_CENTRE, "crowd:spawnCenter = (1e30, 8, 0)", "Guards.crowd:spawnCenter",
         "within 100 km"),
    _set("spawn-radius-1e30", _GUARDS_SPAWN, "uniform float crowd:spawnRadius = 1e30\n",
         "Guards.crowd:spawnRadius", "within 100 km"),
    Case("spawn-disc-past-100km", [_edit(_GUARDS_CENTRE, "crowd:spawnCenter = (99000, 8, 0)"),
                                   _edit(_GUARDS_SPAWN, "uniform float crowd:spawnRadius = 99000\n")],
         "Guards.crowd:spawnRadius", "the spawn disc reaches"),
    # 8. customLayerData
    *_family("seed", r"int seed = 3", "{}", ["int seed = -3", "double seed = 1.5", 'string seed = "three"',
                                             "double seed = 1e30", "int64 seed = 99999999999"],
             "customLayerData:usdcrowd:seed", "a seed is an integer from 0 to 4,294,967,295"),
    *_family("usdcrowd-data", r"dictionary usdcrowd = \{[^}]*\}", "{}",
             ['string usdcrowd = "seed 3"', "int usdcrowd = 3"], "customLayerData:usdcrowd", "must be a dictionary"),
    # 9. lights
    _set("lamp-intensity-negative", LAMP, "float inputs:intensity = -1", "Lamp.inputs:intensity", "must be >= 0"),
    *_family("lamp-exposure", LAMP, LAMP + "\n float inputs:exposure = {}", ["2000", "-2000"],
             "Lamp.inputs:exposure", "must be -64 to 64 stops"),
    _set("lamp-intensity-1e30", LAMP, "float inputs:intensity = 1e30", "Lamp.inputs:intensity",
         "more than the 1e+15 any light gives"),
    _set("lamp-intensity-nan", LAMP, "float inputs:intensity = nan", "Lamp.inputs:intensity", "not a finite value"),
    _add("lamp-colour-negative", LAMP, "color3f inputs:color = (-1, 0.5, 0.5)", "Lamp.inputs:color",
         "must be >= 0 in each channel"),
    _set("lamp-colour-temperature-0", r"colorTemperature = 3200", "colorTemperature = 0",
         "Lamp.inputs:colorTemperature", "must be 100 to 100000 K"),
    _add("dome-texture-missing", SKY, "asset inputs:texture:file = @./sky.exr@", "Sky.inputs:texture:file",
         "@./sky.exr@ not found"),
    _add("dome-texture-is-text", SKY, "asset inputs:texture:file = @./sky.hdr@", "Sky.inputs:texture:file",
         "is not an image", {"sky.hdr": b"a sky, in words\n"}),
    # 10. what validate reports as an error, simulate refuses
    _set("variant-selection-missing", EXHIBITS, _STAND + EXHIBITS, "Stand.variants:look", "selects 'gone'"),
    _set("event-member-nowhere", EXHIBITS, _TALK + EXHIBITS, "Talk.crowd:members", _NOWHERE),
    _add("leader-nowhere", TEACHER, f"rel crowd:leader = <{_NOWHERE}>", "Teacher.crowd:leader", _NOWHERE),
    _set("camera-target-nowhere", r'def Camera "Overview"\n\s+\{',
         f'def Camera "Overview" (\n prepend apiSchemas = ["CameraAgentAPI"]\n)\n{{\n rel crowd:camera:target = '
         f'<{_NOWHERE}>', "Overview.crowd:camera:target", _NOWHERE),
]


@pytest.fixture(scope="module")
def museum_text(tmp_path_factory):
    """A 6-agent museum scenario over frames 1-12."""
    path = tmp_path_factory.mktemp("museum") / "museum.usda"
    assert main(["new", "museum", "-o", str(path), "--agents", "6"]) == 0
    return re.sub(r"endTimeCode = \d+", "endTimeCode = 12", path.read_text())


def _broken(text: str, folder, edits, files=None, name="bad.usda"):
    from PIL import Image

    for pattern, new, count in edits:
        text, n = re.subn(pattern, new, text, count=count)
        assert n, pattern
    for file, content in (files or {}).items():
        if isinstance(content, np.ndarray):
            Image.fromarray(content, mode="F").save(folder / file)
        else:
            (folder / file).write_bytes(content)
    path = folder / name
    path.write_text(text)
    return path


def _written(out) -> list[str]:
    """Files a run left in its output folder (usdcrowd's hidden bookkeeping aside)."""
    if not out.exists():
        return []
    return [str(p.relative_to(out)) for p in out.rglob("*")
            if p.is_file() and not any(part.startswith(".") for part in p.relative_to(out).parts)]


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_a_bad_value_is_one_line_from_simulate_and_validate(museum_text, tmp_path, capfd, case):
    bad = _broken(museum_text, tmp_path, case.edits, case.files)
    out = tmp_path / "shot"
    capfd.readouterr()
    code = main(["simulate", str(bad), "-o", str(out), "--no-progress"])
    captured = capfd.readouterr()
    err = captured.err
    assert code == 2, (code, err)
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert "bad.usda" in err and case.where in err and case.words in err, err
    assert not (out / "shot.usda").exists() and _written(out) == [], _written(out)
    assert main(["validate", str(bad)]) == 1
    report = capfd.readouterr().out
    assert case.where in report and case.words in report, report


def test_validate_reports_every_problem_in_one_run(museum_text, tmp_path, capfd):
    bad = _broken(museum_text, tmp_path, [
        # Two empty groups (Solo and Guards), a giant, a lamp that takes light away, a far exhibit, a group
        # whose spawn radius cannot be read and a leader that follows itself.
        _edit(r"uniform int crowd:clones = 1\n(?=\s+uniform token crowd:condition = \"isolated\")",
              "uniform int crowd:clones = 0\n", 0),
        _edit(r"uniform float crowd:height = [\d.]+", "uniform float crowd:height = 40"),
        _edit(LAMP, "float inputs:intensity = -1"),
        _edit(r"double3 xformOp:translate = \(9, 5, 0\)\n", "double3 xformOp:translate = (9e9, 5, 0)\n"),
        _edit(FAMILY, "uniform float crowd:spawnRadius = nan"),
        _edit(TEACHER, TEACHER + "\n rel crowd:leader = </World/Crowd/Visitors/Students/Teacher>"),
    ])
    capfd.readouterr()
    assert main(["validate", str(bad)]) == 1
    report = capfd.readouterr().out
    expected = ["Solo.crowd:clones: error: empty group", "Guards.crowd:clones: error: empty group",
                "Teacher.crowd:height: error", "Lamp.inputs:intensity: error", "Vase.xformOp:translate: error",
                "Family.crowd:spawnRadius: error: not a finite number"]
    assert all(e in report for e in expected), report
    assert "6 error(s)" in report and "Traceback" not in report, report
    # simulate stops at the first, in one line.
    assert main(["simulate", str(bad), "-o", str(tmp_path / "shot"), "--no-progress"]) == 2
    err = capfd.readouterr().err
    assert err.count("\n") == 1 and "bad.usda" in err and any(e.split(": error")[0] in err for e in expected), err


def test_a_seed_on_the_command_line_is_checked_too(museum_text, tmp_path, capfd):
    scenario = _broken(museum_text, tmp_path, [], name="museum.usda")
    capfd.readouterr()
    assert main(["simulate", str(scenario), "-o", str(tmp_path / "shot"), "--no-progress", "--seed", "-5"]) == 2
    err = capfd.readouterr().err
    assert err.count("\n") == 1 and "--seed" in err and "a seed from 0 to 4,294,967,295" in err, err
    assert not (tmp_path / "shot" / "shot.usda").exists()


@pytest.mark.parametrize("edits", [
    # Edges of the ranges stay accepted: exhibits 90 km away, centimetres, ant-sized agents, 1 and 1000 fps.
    [_edit(STATUE, r"\1double3 xformOp:translate = (-6, 90000, 0)")],
    [_edit(r"metersPerUnit = 1", "metersPerUnit = 0.01")],
    [_edit(FAMILY, FAMILY + "\n uniform float2 crowd:heightRange = (0.04, 0.06)")],
    [_edit(r"timeCodesPerSecond = 24", "timeCodesPerSecond = 1000")],
    [_edit(r"upAxis = \"Z\"", "upAxis = \"Y\"")],
], ids=["exhibit-90km", "centimetres", "ants", "fps-1000", "y-up"])
def test_values_at_the_edges_of_the_ranges_are_accepted(museum_text, tmp_path, capfd, edits):
    good = _broken(museum_text, tmp_path, edits, name="edge.usda")
    capfd.readouterr()
    assert main(["validate", str(good)]) == 0, capfd.readouterr().out
    assert main(["simulate", str(good), "-o", str(tmp_path / "shot"), "--no-progress"]) == 0, capfd.readouterr().err
    assert (tmp_path / "shot" / "shot.usda").exists()
