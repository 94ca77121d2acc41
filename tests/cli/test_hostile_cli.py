"""Careless numbers and names on the command line and in dataset specs: each one line, exit 2, nothing written.

The contract of every case: exit code 2, one to three lines on stderr naming
the option (or the spec's key), no traceback, no output folder left with
anything in it, and the inputs unchanged byte for byte.
"""

from __future__ import annotations

import pytest
from tests.helpers.hung import fails_if_hung
from tests.helpers.shots import cli_museum_shot
from tests.helpers.files import digest_tree

from usdcrowd.cli import main


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    """A museum scenario and its 12-frame shot, shared read-only by every case."""
    return cli_museum_shot(tmp_path_factory.mktemp("hostile_cli"), agents=6, last_frame=12)


def _contract(capsys, argv, words, out, before, inputs_folder):
    with fails_if_hung(60, f"usdcrowd {' '.join(argv)}"):
        code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, (argv, code, err)
    assert 1 <= len(err.strip().splitlines()) <= 3 and "Traceback" not in err, err
    assert words in err, (words, err)
    assert not out.exists() or not [p for p in out.rglob("*") if p.is_file()], list(out.rglob("*"))
    assert digest_tree(inputs_folder) == before


SHOT_CASES = [
    # render
    (["render", "{shot}", "-o", "{out}", "--spp", "0"], "--spp"),
    (["render", "{shot}", "-o", "{out}", "--spp", "1e9"], "--spp"),
    (["render", "{shot}", "-o", "{out}", "--spp", "100000000"], "--spp"),
    (["render", "{shot}", "-o", "{out}", "--people-spp", "1000000000"], "--people-spp"),
    (["render", "{shot}", "-o", "{out}", "--people-spp", "-1"], "--people-spp"),
    (["render", "{shot}", "-o", "{out}", "--max-depth", "0"], "--max-depth"),
    (["render", "{shot}", "-o", "{out}", "--max-depth", "100000"], "--max-depth"),
    (["render", "{shot}", "-o", "{out}", "--exposure", "nan"], "--exposure"),
    (["render", "{shot}", "-o", "{out}", "--exposure", "inf"], "--exposure"),
    (["render", "{shot}", "-o", "{out}", "--exposure", "2000"], "--exposure"),
    (["render", "{shot}", "-o", "{out}", "--seed", "-1"], "--seed"),
    (["render", "{shot}", "-o", "{out}", "--seed", "1e30"], "--seed"),
    (["render", "{shot}", "-o", "{out}", "--seed", "99999999999999999999"], "--seed"),
    (["render", "{shot}", "-o", "{out}", "--motion-blur", "nan"], "--motion-blur"),
    (["render", "{shot}", "-o", "{out}", "--motion-blur", "2"], "--motion-blur"),
    (["render", "{shot}", "-o", "{out}", "--motion-blur", "-0.5"], "--motion-blur"),
    (["render", "{shot}", "-o", "{out}", "--subframes", "1"], "--subframes"),
    (["render", "{shot}", "-o", "{out}", "--subframes", "100000"], "--subframes"),
    (["render", "{shot}", "-o", "{out}", "--resolution", "0x10"], "--resolution"),
    (["render", "{shot}", "-o", "{out}", "--resolution", "100000x10"], "--resolution"),
    (["render", "{shot}", "-o", "{out}", "--resolution", "640by360"], "--resolution"),
    (["render", "{shot}", "-o", "{out}", "--frames", "10:1"], "--frames"),
    (["render", "{shot}", "-o", "{out}", "--frames", "1:10x0"], "--frames"),
    (["render", "{shot}", "-o", "{out}", "--frames", "one"], "--frames"),
    (["render", "{shot}", "-o", "{out}", "--frames", "1:99999999999"], "--frames"),
    (["render", "{shot}", "-o", "{out}", "--frames", "500"], "500"),
    (["render", "{shot}", "-o", "{out}", "--camera", "/World/Nowhere"], "/World/Nowhere"),
    (["render", "{shot}", "-o", "{out}", "--preset", "cinema"], "cinema"),
    (["render", "{shot}", "-o", "{out}", "--workers", "-1"], "--workers"),
    (["render", "{shot}", "-o", "{out}", "--executor", "cloud"], "--executor"),
    (["render", "{shot}", "-o", "{out}", "--sampler", "magic"], "--sampler"),
    (["render", "{shot}", "-o", "{out}", "--working-space", "XYZ"], "--working-space"),
    (["render", "{shot}", "-o", "{out}", "--address", "10.0.0.1:6379"], "--address"),
    (["render", "{shot}", "-o", "{out}", "--spp", "4", "--no-such-option"], "--no-such-option"),
    # preview
    (["preview", "{shot}", "-o", "{out}", "--exposure", "nan"], "--exposure"),
    (["preview", "{shot}", "-o", "{out}", "--exposure", "-1"], "--exposure"),
    (["preview", "{shot}", "-o", "{out}", "--resolution", "1x99999"], "--resolution"),
    (["preview", "{shot}", "-o", "{out}", "--frames", "1:99999999999"], "--frames"),
    (["preview", "{shot}", "-o", "{out}", "--camera", "/World/Nowhere"], "/World/Nowhere"),
    (["preview", "{shot}", "-o", "{out}", "--overlays", "sparkles"], "sparkles"),
    (["preview", "{shot}", "-o", "{out}", "--max-meshes", "-5"], "--max-meshes"),
    (["preview", "{shot}", "-o", "{out}/clip.gif"], "clip.gif"),
    (["preview", "{shot}", "-o", "{out}/clip.avi"], "clip.avi"),
    # the shot as output, or a file as folder
    (["render", "{shot}", "-o", "{shot}"], "would overwrite an input"),
    (["metrics", "{shot}", "-o", "{shot}"], "would overwrite an input"),
    (["simulate", "{shot}", "-o", "{shotdir}"], "would overwrite an input"),
    (["preview", "{shot}", "-o", "{out}", "--sheet", "{shot}"], "would overwrite an input"),
    (["preview", "{shot}", "-o", "{out}", "--sheet", "{scenario}"], "would overwrite an input"),
    (["new", "museum", "-o", "{scenario}", "--scenery", "{scenario}"], "would overwrite an input"),
    (["new", "museum", "-o", "{shot}"], "usdcrowd simulate wrote"),
    (["features", "{shot}", "Teacher", "Guard", "-o", "{shot}"], "would overwrite an input"),
    (["render", "{shot}", "-o", "{shotdir}"], "holds a shot's outputs"),
    (["metrics", "{shot}", "-o", "{shotdir}"], "holds a shot's outputs"),
    (["frame", "{shot}", "--like", "{shotdir}/cameras.usda", "--targets", "auto"], "named as an input"),
    (["preview", "{shot}", "-o", "{out}/p.mp4", "--sheet", "{shotdir}/trajectories.png", "--frames", "1",
      "--resolution", "32x18"], "usdcrowd simulate wrote"),
    (["preview", "{shot}", "-o", "{shotdir}/crowd.usdc"], "crowd.usdc"),
    (["new", "museum", "-o", "{shotdir}/crowd.usdc"], "usdcrowd simulate wrote"),
    # new
    (["new", "museum", "-o", "{out}/s.usda", "--seed", "-5"], "--seed"),
    (["new", "museum", "-o", "{out}/s.usda", "--seed", "1e30"], "--seed"),
    (["new", "museum", "-o", "{out}/s.usda", "--seed", "4294967296"], "--seed"),
    (["new", "museum", "-o", "{out}/s.usda", "--agents", "0"], "--agents"),
    (["new", "museum", "-o", "{out}/s.usda", "--agents", "-3"], "--agents"),
    (["new", "museum", "-o", "{out}/s.usda", "--agents", "1e9"], "--agents"),
    (["new", "museum", "-o", "{out}/s.usda", "--agents", "1000000000"], "--max-agents"),
    (["new", "cathedral", "-o", "{out}/s.usda"], "cathedral"),
    (["new", "museum", "-o", "{out}/s.usda", "--scenery", "{out}/missing.usda"], "missing.usda"),
    (["new", "museum", "-o", "{out}/s.usda", "--max-agents", "0"], "--max-agents"),
    # simulate
    (["simulate", "{scenario}", "-o", "{out}", "--seed", "-1"], "--seed"),
    (["simulate", "{scenario}", "-o", "{out}", "--seed", "0x10"], "--seed"),
    (["simulate", "{scenario}", "-o", "{out}", "--frames", "x"], "--frames"),
    (["simulate", "{scenario}", "-o", "{out}", "--frames", "0"], "--frames"),
    (["simulate", "{scenario}", "-o", "{out}", "--frames", "1:240x2"], "no stride"),
    (["simulate", "{scenario}", "-o", "{out}", "--max-agents", "2"], "--max-agents"),
    (["simulate", "{scenario}", "-o", "{out}", "--max-frames", "5"], "--max-frames"),
    (["simulate", "{out}/missing.usda", "-o", "{out}"], "missing.usda"),
    (["simulate", "{scenario}"], "-o"),
    # cameras, metrics, features, inspect, validate
    (["cameras", "{shot}", "--count", "-1"], "--count"),
    (["cameras", "{shot}", "--static", "-2"], "--static"),
    (["cameras", "{shot}", "--seed", "-3"], "--seed"),
    (["metrics", "{shot}", "-o", "{out}", "--counts", "0"], "--counts"),
    (["metrics", "{shot}", "-o", "{out}", "--counts", "4,x"], "--counts"),
    (["metrics", "{shot}", "-o", "{out}", "--seed", "-1"], "--seed"),
    (["features", "{shot}", "Nobody", "Noone", "-o", "{out}"], "Nobody"),
    (["features", "{shot}", "Nobody", "Noone", "-o", "{out}", "--resolution", "0x0"], "--resolution"),
    (["inspect", "{out}/missing.usda"], "missing.usda"),
    (["inspect", "{shot}", "--max-agents", "2"], "--max-agents"),
    (["validate", "{out}/missing.usda"], "missing.usda"),
    (["frame", "{shot}", "--behavior", "orbit", "--targets", "A"], "--targets"),
    (["frame", "{shot}", "--behavior", "spin", "--targets", "auto"], "--behavior"),
    (["frame", "{shot}", "--behavior", "orbit", "--targets", "auto", "--focal-length", "0"], "--focal-length"),
    (["frame", "{shot}", "--behavior", "orbit", "--targets", "auto", "--shot", "huge"], "--shot"),
    (["frame", "{shot}", "--behavior", "orbit", "--targets", "auto", "--switch", "x", "A", "B"], "--switch"),
    (["frame", "{shot}", "--behavior", "orbit", "--targets", "auto", "--span", "0"], "--span"),
    (["dataset", "{out}/missing.toml", "-o", "{out}/ds"], "missing.toml"),
    (["dataset", "{scenario}", "-o", "{out}/ds"], "not valid TOML"),
    (["dataset", "{out}/missing.toml", "-o", "{out}/ds", "--workers", "0"], "--workers"),
    (["demo", "-o", "{shot}"], "exists and is not a folder"),
    (["nonsense"], "invalid choice"),
]


@pytest.mark.parametrize("argv, words", SHOT_CASES, ids=[" ".join(a[:1] + a[3:]) for a, _ in SHOT_CASES])
def test_a_careless_command_line_is_one_line_and_writes_nothing(inputs, tmp_path, capsys, argv, words):
    scenario, shot_dir = inputs
    folder = shot_dir.parent
    before = digest_tree(folder)
    out = tmp_path / "out"
    names = {"shot": shot_dir / "shot.usda", "shotdir": shot_dir, "scenario": scenario, "out": out}
    argv = [a.format(**names) for a in argv]
    if argv[0] not in ("inspect", "validate", "nonsense", "new", "features"):
        argv.append("--no-progress")
    _contract(capsys, argv, words, out, before, folder)


SPEC_CASES = [
    ("[light]\nsun_azimuth = [-1e308, 1e308]\n", "light.sun_azimuth"),
    ("[light]\nsun_azimuth = [0, 1e300]\n", "light.sun_azimuth"),
    ("[light]\nsun_strength = [-1, 2]\n", "light.sun_strength"),
    ("[light]\ncolor_temperature = [10, 20]\n", "light.color_temperature"),
    ("[light]\nsun_elevation = nan\n", "light.sun_elevation"),
    ("[light]\nsun_elevation = inf\n", "light.sun_elevation"),
    ("[scene]\nagents = [1, 1000000000]\n", "scene.agents"),
    ("[scene]\nagents = [0, 10]\n", "scene.agents"),
    ("[scene]\nagents = [5.5, 10]\n", "scene.agents"),
    ("[scene]\nagents = \"many\"\n", "scene.agents"),
    ("[scene]\ntemplates = []\n", "scene.templates"),
    ("[scene]\nsceneries = [\"nowhere.usda\"]\n", "scene.sceneries"),
    ("[cameras]\nfocal_length = [10, 1000000]\n", "cameras.focal_length"),
    ("[cameras]\ndistance = [0, 5]\n", "cameras"),
    ("[cameras]\nsteering = [0, 100]\n", "cameras.steering"),
    ("[cameras]\nstatic = 17\n", "cameras.static"),
    ("[cameras]\ntoric_shots = [\"huge\"]\n", "cameras.toric_shots"),
    ("[render]\nspp = 0\n", "render.spp"),
    ("[render]\nspp = 100000000\n", "render.spp"),
    ("[render]\npreset = \"cinema\"\n", "render.preset"),
    ("[render]\nresolution = [100000, 10]\n", "render.resolution"),
    ("[dataset]\nsequences = 2000000\n", "dataset.sequences"),
    ("[dataset]\nsequences = 1000000\n", "dataset.sequences"),
    ("[dataset]\nframes = 1\n", "dataset.frames"),
    ("[dataset]\nstride = 0\n", "dataset.stride"),
    ("[dataset]\nseed = -1\n", "dataset.seed"),
    ("[dataset]\nsplit = { train = -1 }\n", "dataset.split"),
    ("[dataset]\nsplit = { holdout = 1 }\n", "dataset.split"),
    ("[appearance]\npalettes = [\"neon\"]\n", "appearance.palettes"),
    ("dataset = 3\n", "dataset"),
]


@pytest.mark.parametrize("text, key", SPEC_CASES, ids=[k for _, k in SPEC_CASES])
def test_a_careless_dataset_spec_is_one_line_and_writes_nothing(inputs, tmp_path, capsys, text, key):
    spec = tmp_path / "spec.toml"
    spec.write_text(text)
    before = digest_tree(tmp_path)
    out = tmp_path / "ds"
    _contract(capsys, ["dataset", str(spec), "-o", str(out), "--no-progress"], key, out,
              before, tmp_path)


def test_a_failed_dataset_leaves_no_spec_that_refuses_the_corrected_one(tmp_path, capsys):
    """A run that failed before making anything must not lock the folder to its spec."""
    from tests.helpers.datasets import write_spec

    bad = tmp_path / "bad.toml"
    bad.write_text(write_spec(tmp_path).read_text().replace("[scene]", "[scene]\nsceneries = [\"gone.usda\"]"))
    out = tmp_path / "ds"
    assert main(["dataset", str(bad), "-o", str(out), "--no-progress"]) == 2
    capsys.readouterr()
    good = write_spec(tmp_path, seed=5, name="good.toml")
    assert main(["dataset", str(good), "-o", str(out), "--no-progress", "--sequences", "0"]) == 0, \
        capsys.readouterr().err
