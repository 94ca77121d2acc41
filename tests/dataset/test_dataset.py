"""usdcrowd dataset: seeded plans written into the stages, MOT and COCO the field's tools read, resumable, on Ray."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mitsuba")
pytest.importorskip("pycocotools")

from usdcrowd.cli import main  # noqa: E402
from usdcrowd.dataset import baseline, layout  # noqa: E402
from usdcrowd.dataset.run import make_dataset  # noqa: E402
from usdcrowd.dataset.spec import assign_splits, draw_plan, load_spec  # noqa: E402
from usdcrowd.core.errors import UsdcrowdError  # noqa: E402

from tests.helpers.datasets import write_spec  # noqa: E402


@pytest.fixture(scope="module")
def tiny_dataset(tmp_path_factory):
    """Three sequences, every camera four frames, made in this process."""
    folder = tmp_path_factory.mktemp("dataset")
    spec = write_spec(folder)
    result = make_dataset(spec, folder / "out", executor="inline", progress=False)
    return spec, folder / "out", result


def _videos(root: Path) -> dict[str, list[Path]]:
    return {split: sorted(p for p in layout.mot_dir(root, split).iterdir() if p.is_dir())
            for split in ("train", "val", "test") if layout.mot_dir(root, split).is_dir()}


def test_each_sequences_plan_is_drawn_from_the_seed_and_its_index(tmp_path):
    spec = load_spec(write_spec(tmp_path))
    more = load_spec(write_spec(tmp_path, name="more.toml"))
    more.sequences = 9
    strip = lambda p: {k: v for k, v in p.items() if k not in ("split", "digest")}  # noqa: E731
    for i in range(3):
        assert strip(draw_plan(spec, i, "train")) == strip(draw_plan(more, i, "train"))
    assert draw_plan(spec, 0, "train") != draw_plan(spec, 1, "train")
    other = load_spec(write_spec(tmp_path, seed=4, name="other.toml"))
    assert strip(draw_plan(other, 0, "train")) != strip(draw_plan(spec, 0, "train"))
    splits = assign_splits(more)
    assert sorted(splits) == sorted(["train"] * 3 + ["val"] * 3 + ["test"] * 3)


def test_every_drawn_value_is_in_the_sequences_stage(tiny_dataset):
    """Plain usd-core reads the plan back from the scenario, and the sun it lit the scene with."""
    _, root, _ = tiny_dataset
    for seq in sorted((root / "sequences").iterdir()):
        plan = json.loads((seq / "plan.json").read_text())["plan"]
        script = textwrap.dedent(f'''
            import json, math
            from pxr import Usd, UsdGeom, UsdLux
            stage = Usd.Stage.Open({os.fspath(seq / "scenario.usda")!r})
            data = stage.GetRootLayer().customLayerData["usdcrowd"]
            sun = next(p for p in stage.Traverse() if p.IsA(UsdLux.DistantLight))
            m = UsdGeom.Xformable(sun).ComputeLocalToWorldTransform(0)
            d = m.TransformDir((0, 0, -1)).GetNormalized()      # the way the light travels
            print(json.dumps({{"plan": json.loads(data["dataset"]), "palette": data["palette"], "seed": data["seed"],
                              "elevation": math.degrees(math.asin(-d[2])),
                              "azimuth": math.degrees(math.atan2(-d[1], -d[0])) % 360,
                              "kelvin": UsdLux.DistantLight(sun).GetColorTemperatureAttr().Get()}}))
        ''')
        done = subprocess.run([sys.executable, "-I", "-c", script], capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
        got = json.loads(done.stdout)
        assert got["plan"] == plan and got["palette"] == plan["palette"] and got["seed"] == plan["seed"]
        assert got["elevation"] == pytest.approx(plan["light"]["sun_elevation"], abs=1e-3)
        assert got["azimuth"] == pytest.approx(plan["light"]["sun_azimuth"], abs=1e-3)
        assert got["kelvin"] == pytest.approx(plan["light"]["color_temperature"], rel=1e-6)


def test_pycocotools_reads_every_split_and_its_masks_are_the_id_pass(tiny_dataset):
    from pycocotools import mask as mask_utils
    from pycocotools.coco import COCO

    from usdcrowd.render.final.exr import read_frame_exr

    _, root, result = tiny_dataset
    videos = _videos(root)
    total_images = 0
    for split, folders in videos.items():
        coco = COCO(os.fspath(root / "coco" / f"{split}.json"))
        frames = sum(int(next(ln for ln in (f / "seqinfo.ini").read_text().splitlines()
                              if ln.startswith("seqLength")).split("=")[1]) for f in folders)
        assert len(coco.getImgIds()) == frames
        total_images += frames
        assert len(coco.dataset["videos"]) == len(folders)
        for img in coco.loadImgs(coco.getImgIds()):
            assert (root / img["file_name"]).is_file() and img["frame_id"] >= 1 and img["video_id"] >= 1
        # One image checked pixel by pixel against its EXR's id pass.
        ann_ids = coco.getAnnIds()
        assert ann_ids, split
        ann = coco.loadAnns(ann_ids[len(ann_ids) // 2])[0]
        img = coco.loadImgs(ann["image_id"])[0]
        video = next(v for v in coco.dataset["videos"] if v["id"] == img["video_id"])
        cam = video["camera"].rsplit("/", 1)[-1]
        record = json.loads((root / "mot" / f"USDCROWD-{split}" / video["name"] / "json"
                             / f"{img['frame_id']:06d}.json").read_text())
        _, channels = read_frame_exr(root / "sequences" / video["sequence"] / "render" / cam
                                     / record["files"]["exr"])
        truth = channels["id"].astype(np.int64) == ann["track_id"]
        decoded = mask_utils.decode(ann["segmentation"]).astype(bool)
        assert np.array_equal(decoded, truth) and ann["area"] == truth.sum()
        assert isinstance(ann["segmentation"]["counts"], str)        # compressed RLE
    assert total_images == result.frames


def test_trackeval_scores_the_ground_truth_1_and_the_baseline_sensibly(tiny_dataset):
    pytest.importorskip("trackeval")
    _, root, _ = tiny_dataset
    for split in _videos(root):
        baseline.ground_truth_as_tracker(root, split)
        baseline.run_baseline(root, split, seed=1, drop=0.3)
        scores = baseline.evaluate(root, split, ["gt", "iou"])
        assert scores["gt"] == {"HOTA": pytest.approx(1.0), "MOTA": pytest.approx(1.0), "IDF1": pytest.approx(1.0)}
        assert 0.2 < scores["iou"]["HOTA"] < 0.99 and 0.2 < scores["iou"]["MOTA"] < 0.99, scores


def test_the_card_counts_what_the_files_hold(tiny_dataset):
    from pycocotools.coco import COCO

    _, root, _ = tiny_dataset
    card = (root / "README.md").read_text()
    assert (root / "card.png").stat().st_size > 10_000
    for split in _videos(root):
        coco = COCO(os.fspath(root / "coco" / f"{split}.json"))
        anns = coco.loadAnns(coco.getAnnIds())
        tracks = {(a["video_id"], a["track_id"]) for a in anns}
        row = next(ln for ln in card.splitlines() if ln.startswith(f"| {split} |"))
        cells = [c.strip().replace(",", "") for c in row.strip("|").split("|")]
        assert int(cells[3]) == len(coco.getImgIds()) and int(cells[4]) == len(anns) and int(cells[5]) == len(tracks)


def test_the_manifest_holds_every_files_sha256(tiny_dataset):
    import hashlib

    spec, root, _ = tiny_dataset
    doc = json.loads((root / "manifest.json").read_text())
    assert doc["state"] == "complete" and doc["spec_sha256"] == load_spec(spec).digest()
    on_disk = {os.fspath(p.relative_to(root)) for p in root.rglob("*") if p.is_file() and p.name != "manifest.json"
               and "trackers" not in p.parts}
    assert on_disk <= set(doc["files"])
    for rel in sorted(on_disk)[::7]:
        assert hashlib.sha256((root / rel).read_bytes()).hexdigest() == doc["files"][rel]["sha256"], rel


def test_a_run_again_finishes_only_what_is_missing(tiny_dataset, tmp_path):
    spec, root, _ = tiny_dataset
    copy = tmp_path / "copy"
    shutil.copytree(root, copy)
    cam = sorted((copy / "sequences").glob("*/render/*"))[0]
    victim = sorted((cam / "png").iterdir())[1]
    old = victim.read_bytes()
    victim.unlink()                                   # as if killed before this frame was written
    (copy / "coco" / "train.json").unlink()
    again = make_dataset(spec, copy, executor="inline", progress=False)
    assert again.prepared == 0 and again.rendered == 1
    assert victim.read_bytes() == old                 # the same bytes again
    assert (copy / "coco" / "train.json").read_bytes() == (root / "coco" / "train.json").read_bytes()


def test_a_run_again_keeps_what_a_user_put_beside_the_merged_files(tiny_dataset, tmp_path):
    spec, root, _ = tiny_dataset
    copy = tmp_path / "copy"
    shutil.copytree(root, copy)
    notes = [copy / "mot" / "notes.txt", copy / "coco" / "my_subset" / "ids.txt",
             copy / "mot" / "seqmaps" / "USDCROWD-train-mine.txt", copy / "coco" / "train_small.json"]
    for path in notes:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("mine")
    make_dataset(spec, copy, executor="inline", progress=False)
    assert all(p.read_text() == "mine" for p in notes)
    assert (copy / "coco" / "train.json").read_bytes() == (root / "coco" / "train.json").read_bytes()


def test_a_spec_seed_may_be_any_32_bit_number(tmp_path):
    spec = write_spec(tmp_path, seed=20240611)
    assert load_spec(spec).seed == 20240611


def test_a_changed_spec_is_refused_unless_forced(tiny_dataset, tmp_path):
    spec, root, _ = tiny_dataset
    copy = tmp_path / "copy"
    shutil.copytree(root, copy)
    changed = write_spec(tmp_path, seed=11)
    with pytest.raises(UsdcrowdError, match="another spec.*--force"):
        make_dataset(changed, copy, executor="inline", progress=False)
    assert main(["dataset", str(changed), "-o", str(copy), "--executor", "inline", "--no-progress"]) == 2
    forced = make_dataset(changed, copy, executor="inline", progress=False, force=True)
    assert forced.prepared == 3
    assert json.loads((copy / "manifest.json").read_text())["spec_sha256"] == load_spec(changed).digest()


def test_one_sequence_is_remade_alone_identically(tiny_dataset, tmp_path):
    spec, root, _ = tiny_dataset
    alone = make_dataset(spec, tmp_path / "alone", executor="inline", progress=False, only=[1])
    assert alone.sequences == 1
    seq = json.loads((root / "sequences" / "seq_0001" / "plan.json").read_text())
    assert json.loads((tmp_path / "alone" / "sequences" / "seq_0001" / "plan.json").read_text())["plan"] == seq["plan"]
    for gt in (tmp_path / "alone" / "mot").glob("*/*/gt/gt.txt"):
        assert gt.read_text() == (root / gt.relative_to(tmp_path / "alone")).read_text()


@pytest.mark.parametrize("text, key", [
    ("[dataset]\nsequences = 0\n", "dataset.sequences"),
    ("[scene]\ntemplates = [\"nowhere\"]\n", "scene.templates"),
    ("[light]\nsun_elevation = [50, 10]\n", "light.sun_elevation"),
    ("[cameras]\ntoric = [\"spin\"]\n", "cameras.toric"),
    ("[render]\nresolution = [0, 10]\n", "render.resolution"),
    ("[render]\npeople_spp = -1\n", "render.people_spp"),
    ("[dataset]\nframez = 3\n", "dataset.framez"),
    ("[dataset\n", "not valid TOML"),
])
def test_a_bad_spec_is_a_one_line_error_naming_the_key(tmp_path, capsys, text, key):
    spec = tmp_path / "bad.toml"
    spec.write_text(text)
    assert main(["dataset", str(spec), "-o", str(tmp_path / "out"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(spec) in err and key in err, err
    assert not (tmp_path / "out" / "manifest.json").exists()


def test_the_spec_sets_the_peoples_samples_or_leaves_the_presets(tmp_path):
    from usdcrowd.dataset.run import _settings
    from usdcrowd.dataset.spec import load_spec
    from usdcrowd.render.settings import load_presets

    spec = write_spec(tmp_path)
    assert _settings(load_spec(spec)).people_spp == load_presets()["preview"]["people_spp"]
    spec.write_text(spec.read_text().replace("spp = 2", "spp = 2\npeople_spp = 9"))
    assert _settings(load_spec(spec)).people_spp == 9


@pytest.mark.ray
def test_ray_with_two_workers_makes_the_same_dataset_and_opens_no_cluster_it_was_not_given(tiny_dataset, tmp_path,
                                                                                          monkeypatch):
    pytest.importorskip("ray")
    spec, root, _ = tiny_dataset
    # A cluster address in the environment must not be used: only --address names one.
    monkeypatch.setenv("RAY_ADDRESS", "127.0.0.1:1")
    result = make_dataset(spec, tmp_path / "ray", executor="ray", workers=2, progress=False)
    assert result.rendered == result.frames
    for gt in (root / "mot").glob("*/*/gt/gt.txt"):
        assert (tmp_path / "ray" / gt.relative_to(root)).read_text() == gt.read_text()


def test_a_killed_run_resumes_where_it_stopped(tmp_path):
    spec = write_spec(tmp_path)
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "usdcrowd", "dataset", str(spec), "-o", str(out), "--executor", "inline",
           "--no-progress"]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and len(list(out.glob("sequences/*/render/*/png/*.png"))) < 3:
        time.sleep(0.2)
    proc.kill()
    proc.wait()
    before = len(list(out.glob("sequences/*/render/*/png/*.png")))
    assert before >= 3 and not (out / "coco").exists()
    again = make_dataset(spec, out, executor="inline", progress=False)
    assert again.rendered <= again.frames - before + 1     # the frame being written when killed, at most
    assert json.loads((out / "manifest.json").read_text())["state"] == "complete"


def test_two_local_processes_make_the_same_dataset(tiny_dataset, tmp_path):
    spec, root, _ = tiny_dataset
    result = make_dataset(spec, tmp_path / "local", executor="local", workers=2, progress=False)
    assert result.rendered == result.frames
    for coco in (root / "coco").glob("*.json"):
        assert (tmp_path / "local" / "coco" / coco.name).read_bytes() == coco.read_bytes()


def test_remaking_one_sequence_in_a_dataset_keeps_the_others_in_it(tiny_dataset, tmp_path):
    spec, root, _ = tiny_dataset
    copy = tmp_path / "copy"
    shutil.copytree(root, copy)
    again = make_dataset(spec, copy, executor="inline", progress=False, only=[2])
    assert again.sequences == 3 and again.rendered == 0
    for coco in (root / "coco").glob("*.json"):
        assert (copy / "coco" / coco.name).read_bytes() == coco.read_bytes()
    assert json.loads((copy / "manifest.json").read_text())["state"] == "complete"


@pytest.mark.slow
@pytest.mark.ray
def test_a_ray_cluster_given_by_address_makes_the_same_dataset(tiny_dataset, tmp_path):
    """A local two-CPU cluster started as on a head node (`ray start --head`), joined through --address.

    Everything Ray runs in other processes: Ray keeps per-process state that a
    cluster joined here would leave to the tests after this one.
    """
    pytest.importorskip("ray")
    from tests.helpers.ray import ray_head

    spec, root, _ = tiny_dataset
    port = 26379 + os.getpid() % 1000
    with ray_head(port) as env:
        made = subprocess.run([sys.executable, "-m", "usdcrowd", "dataset", str(spec), "-o", str(tmp_path / "cluster"),
                               "--executor", "ray", "--address", f"127.0.0.1:{port}", "--no-progress"],
                              capture_output=True, text=True, env=env, timeout=600)
    assert made.returncode == 0, made.stderr[-2000:]
    for gt in (root / "mot").glob("*/*/gt/gt.txt"):
        assert (tmp_path / "cluster" / gt.relative_to(root)).read_text() == gt.read_text()


def test_a_dcc_scenery_is_used_and_its_own_sun_set_to_the_time_of_day(tmp_path):
    """A Y-up, centimetre scenery bringing its own sun: the crowd walks in it and the sun's world direction
    is the plan's (through the scenery's placement transform)."""
    (tmp_path / "hall.usda").write_text(textwrap.dedent('''\
        #usda 1.0
        (
            defaultPrim = "Hall"
            metersPerUnit = 0.01
            upAxis = "Y"
        )
        def Xform "Hall"
        {
            def Mesh "Floor"
            {
                int[] faceVertexCounts = [4]
                int[] faceVertexIndices = [0, 1, 2, 3]
                point3f[] points = [(-1500, 0, 1500), (1500, 0, 1500), (1500, 0, -1500), (-1500, 0, -1500)]
            }
            def DistantLight "Sun"
            {
                bool inputs:normalize = true
                float inputs:intensity = 2
                float3 xformOp:rotateXYZ = (-60, 20, 0)
                uniform token[] xformOpOrder = ["xformOp:rotateXYZ"]
            }
        }
        '''))
    spec = tmp_path / "spec.toml"
    spec.write_text(textwrap.dedent('''\
        [dataset]
        sequences = 1
        frames = 2
        [scene]
        templates = ["museum"]
        sceneries = ["hall.usda"]
        agents = [6, 6]
        [cameras]
        steering = [0, 0]
        static = 1
        [render]
        preset = "preview"
        resolution = [96, 54]
        spp = 1
        '''))
    result = make_dataset(spec, tmp_path / "out", executor="inline", progress=False)
    assert result.frames == 2
    seq = tmp_path / "out" / "sequences" / "seq_0000"
    plan = json.loads((seq / "plan.json").read_text())["plan"]
    from pxr import Gf, Usd, UsdGeom, UsdLux

    stage = Usd.Stage.Open(str(seq / "scenario.usda"))
    suns = [p for p in stage.Traverse() if p.IsA(UsdLux.DistantLight)]
    assert [str(p.GetPath()) for p in suns] == ["/World/Scenery/Hall/Sun"]     # the template's sun is gone
    d = UsdGeom.Xformable(suns[0]).ComputeLocalToWorldTransform(0).TransformDir(Gf.Vec3d(0, 0, -1)).GetNormalized()
    assert np.degrees(np.arcsin(-d[2])) == pytest.approx(plan["light"]["sun_elevation"], abs=1e-3)
    assert np.degrees(np.arctan2(-d[1], -d[0])) % 360 == pytest.approx(plan["light"]["sun_azimuth"], abs=1e-3)


def test_the_cards_crowd_density_is_people_within_two_metres_per_square_metre(tiny_dataset):
    """Recounted by brute force (every pair's distance) at the same frames, for every sequence."""
    from usdcrowd.dataset.scenario import DENSITY_BINS, DENSITY_RADIUS, densities, density_frames
    from usdcrowd.scenario.shot_scene import ShotScene

    _, root, _ = tiny_dataset
    for seq in sorted((root / "sequences").iterdir()):
        prepared = json.loads((seq / "plan.json").read_text())["prepared"]
        scene = ShotScene(prepared["shot"])
        expected = np.zeros(len(DENSITY_BINS) - 1, int)
        for t in density_frames(scene.time_codes):
            poses = scene.agents(float(t))
            p = poses.joints_world[poses.visible, 0, 3, :2]
            d = np.linalg.norm(p[:, None] - p[None], axis=-1)
            density = (d <= DENSITY_RADIUS).sum(1) / (np.pi * DENSITY_RADIUS ** 2)
            np.testing.assert_allclose(densities(scene, t), density)
            expected += np.histogram(np.minimum(density, DENSITY_BINS[-1] - 1e-9), DENSITY_BINS)[0]
        assert prepared["density"] == expected.tolist(), seq.name
        assert sum(expected) == sum(len(densities(scene, t)) for t in density_frames(scene.time_codes)) > 0


def test_each_cameras_mot_folder_is_written_when_its_last_frame_is_in(tmp_path, monkeypatch):
    """By the time the run merges COCO and the card, every camera's MOT folder is already there."""
    import usdcrowd.dataset.run as run

    seen = {}
    real_merge = run.merge

    def merge(out, spec, sequences, written):
        seen["videos"] = {f.name for f in (Path(out) / "mot").glob("USDCROWD-*/*") if (f / "gt" / "gt.txt").is_file()}
        seen["expected"] = {layout.video_name(s.name, c) for s in sequences for c, _ in s.cameras}
        seen["coco"] = (Path(out) / "coco").exists()
        return real_merge(out, spec, sequences, written)

    monkeypatch.setattr(run, "merge", merge)
    make_dataset(write_spec(tmp_path), tmp_path / "out", executor="inline", progress=False)
    assert seen["videos"] == seen["expected"] and len(seen["expected"]) >= 3 and not seen["coco"]


def test_sequences_made_under_other_render_settings_are_not_merged_as_finished(tiny_dataset, tmp_path):
    """--force with a new spp, re-making sequence 0 alone: the others' frames are stale, so left out."""
    spec, root, _ = tiny_dataset
    copy = tmp_path / "copy"
    shutil.copytree(root, copy)
    changed = tmp_path / "spp.toml"
    changed.write_text(Path(spec).read_text().replace("spp = 2", "spp = 1"))
    again = make_dataset(changed, copy, executor="inline", progress=False, force=True, only=[0])
    assert again.sequences == 1
    assert json.loads((copy / "manifest.json").read_text())["state"] == "partial"


def test_frames_rendered_under_other_presets_are_rendered_again(tiny_dataset, tmp_path, monkeypatch):
    """An edit of presets.toml changes the render settings but not the spec or its plans: no frame made under
    the old settings is kept, neither through its camera's manifest nor adopted from disk (its EXR header
    names the settings it was rendered with)."""
    import dataclasses

    import usdcrowd.dataset.run as run

    spec, root, first = tiny_dataset
    copy = tmp_path / "copy"
    shutil.copytree(root, copy)
    edited = run._settings

    def brighter(s):
        return dataclasses.replace(edited(s), exposure=edited(s).exposure + 1.0)

    monkeypatch.setattr(run, "_settings", brighter)
    again = make_dataset(spec, copy, executor="inline", progress=False)
    assert again.prepared == 0 and again.rendered == again.frames == first.frames
    png = sorted((copy / "sequences").glob("*/render/*/png/*.png"))[0]
    assert png.read_bytes() != (root / png.relative_to(copy)).read_bytes()
