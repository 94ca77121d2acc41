"""Inputs are sacred, one writer per output: every command tried as a careless or unlucky user would."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from usdcrowd.cli import main

from tests.helpers.files import digest_tree
from tests.helpers.shots import cli_museum_shot

USDCROWD = [sys.executable, "-m", "usdcrowd"]


def one_line_error(capsys, *words) -> str:
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    for w in words:
        assert w in err, (w, err)
    return err


@pytest.fixture(scope="module")
def museum_shot(tmp_path_factory):
    """A 6-agent, 12-frame museum scenario and its shot, made by the command line (so usdcrowd owns them)."""
    return cli_museum_shot(tmp_path_factory.mktemp("guarded"), agents=6, last_frame=12)


@pytest.fixture
def shot_copy(museum_shot, tmp_path):
    """A private copy of the museum shot, made again by usdcrowd so that it owns every file."""
    scenario, _ = museum_shot
    shot = tmp_path / "shot"
    assert main(["simulate", str(scenario), "-o", str(shot), "--frames", "1:12", "--no-progress"]) == 0
    return shot


# ------------------------------------------------------------------ inputs are never written
def test_preview_refuses_a_sheet_that_is_its_own_shot(museum_shot, tmp_path, capsys):
    _, shot = museum_shot
    before = digest_tree(shot)
    capsys.readouterr()
    code = main(["preview", str(shot / "shot.usda"), "-o", str(tmp_path / "p"), "--sheet", str(shot / "shot.usda"),
                 "--no-progress"])
    assert code == 2
    one_line_error(capsys, "would overwrite an input", "shot.usda")
    assert digest_tree(shot) == before and not (tmp_path / "p").exists()


def test_simulate_refuses_to_write_a_shot_over_its_own_scenario(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    scenario = out / "shot.usda"            # a scenario that happens to be named like a shot
    assert main(["new", "museum", "-o", str(scenario), "--agents", "6"]) == 0
    before = scenario.read_bytes()
    capsys.readouterr()
    assert main(["simulate", str(scenario), "-o", str(out), "--frames", "1:6", "--no-progress"]) == 2
    one_line_error(capsys, "would overwrite an input", "shot.usda")
    assert scenario.read_bytes() == before
    assert not (out / "crowd.usdc").exists()


def test_simulate_refuses_to_write_a_shot_into_itself(shot_copy, capsys):
    before = digest_tree(shot_copy)
    capsys.readouterr()
    assert main(["simulate", str(shot_copy / "shot.usda"), "-o", str(shot_copy), "--no-progress"]) == 2
    one_line_error(capsys, "would overwrite an input")
    assert digest_tree(shot_copy) == before


def test_new_refuses_to_write_over_its_scenery(tmp_path, capsys, museum_shot):
    town = tmp_path / "town.usda"
    town.write_text('#usda 1.0\n(\n    defaultPrim = "Town"\n    upAxis = "Z"\n    metersPerUnit = 1\n)\n'
                    'def Xform "Town"\n{\n    def Cube "Kiosk"\n    {\n        double size = 2\n    }\n}\n')
    before = town.read_bytes()
    capsys.readouterr()
    assert main(["new", "museum", "-o", str(town), "--scenery", str(town)]) == 2
    one_line_error(capsys, "would overwrite an input", "town.usda")
    assert town.read_bytes() == before


def test_new_refuses_to_replace_a_users_file_unless_forced(tmp_path, capsys):
    mine = tmp_path / "museum.usda"
    mine.write_text("#usda 1.0\n# my own notes\n")
    capsys.readouterr()
    assert main(["new", "museum", "-o", str(mine), "--agents", "6"]) == 2
    one_line_error(capsys, "not written by usdcrowd", "--force")
    assert mine.read_text() == "#usda 1.0\n# my own notes\n"
    assert main(["new", "museum", "-o", str(mine), "--agents", "6", "--force"]) == 0
    assert "CrowdGroup" in mine.read_text()
    # Its own file it replaces without being asked.
    assert main(["new", "museum", "-o", str(mine), "--agents", "8"]) == 0


# ------------------------------------------------------------------ folders usdcrowd did not make
def test_an_output_folder_holding_a_users_files_is_refused_and_never_touched(museum_shot, tmp_path, capsys):
    scenario, _ = museum_shot
    out = tmp_path / "mine"
    (out / "coco").mkdir(parents=True)
    (out / "coco" / "instances.json").write_text("{}")
    (out / "notes.txt").write_text("keep me")
    before = digest_tree(out)
    capsys.readouterr()
    assert main(["simulate", str(scenario), "-o", str(out), "--frames", "1:6", "--no-progress"]) == 2
    one_line_error(capsys, "did not write", "coco/", "notes.txt", "--force")
    assert digest_tree(out) == before
    # Forced: written beside them, theirs untouched.
    assert main(["simulate", str(scenario), "-o", str(out), "--frames", "1:6", "--no-progress", "--force"]) == 0
    assert (out / "shot.usda").is_file()
    assert {k: v for k, v in digest_tree(out).items() if k in before} == before


def test_a_shot_edited_after_simulate_keeps_the_users_edits(museum_shot, shot_copy, capsys):
    """shot.usda is the user's layer: simulate again updates only what usdcrowd owns in it (here the frames);
    the prim added stays, and the hand-written text (a comment USD would not write) is kept in the record."""
    from pxr import Sdf

    scenario, _ = museum_shot
    shot = shot_copy / "shot.usda"
    text = shot.read_text() + '\n# my layout edits\nover "World"\n{\n    def Xform "MyProp"\n    {\n    }\n}\n'
    shot.write_text(text)
    capsys.readouterr()
    assert main(["simulate", str(scenario), "-o", str(shot_copy), "--frames", "1:6", "--no-progress"]) == 0
    layer = Sdf.Layer.OpenAsAnonymous(str(shot))
    assert layer.GetPrimAtPath("/World/MyProp") and layer.endTimeCode == 6
    assert (shot_copy / ".usdcrowd" / "shot.usda.previous").read_text() == text


def test_a_shot_usda_rewritten_into_another_stage_is_never_replaced(museum_shot, shot_copy, capsys):
    """Only a shot's own layer is merged into: a shot.usda the user turned into a stage of their own (no
    usdcrowd record in it) is refused like any file usdcrowd did not write, and stays as it is."""
    scenario, _ = museum_shot
    shot = shot_copy / "shot.usda"
    shot.write_text('#usda 1.0\ndef Xform "Mine"\n{\n}\n')
    before = digest_tree(shot_copy)
    capsys.readouterr()
    assert main(["simulate", str(scenario), "-o", str(shot_copy), "--frames", "1:6", "--no-progress"]) == 2
    one_line_error(capsys, "shot.usda", "changed since")
    assert digest_tree(shot_copy) == before


def test_simulate_again_into_its_own_shot_replaces_it(museum_shot, shot_copy, capsys):
    scenario, _ = museum_shot
    assert main(["simulate", str(scenario), "-o", str(shot_copy), "--frames", "1:6", "--no-progress"]) == 0
    assert "endTimeCode = 6" in (shot_copy / "shot.usda").read_text()


def test_cameras_keeps_a_hand_edited_cameras_layer_unless_forced(shot_copy, capsys):
    cams = shot_copy / "cameras.usda"
    cams.write_text(cams.read_text() + "\n# a camera added by hand\n")
    before = cams.read_bytes()
    capsys.readouterr()
    assert main(["cameras", str(shot_copy / "shot.usda"), "--count", "1", "--no-progress"]) == 2
    one_line_error(capsys, "cameras.usda", "changed since usdcrowd wrote it", "--force")
    assert cams.read_bytes() == before
    assert main(["cameras", str(shot_copy / "shot.usda"), "--count", "1", "--no-progress", "--force"]) == 0
    assert b"a camera added by hand" not in cams.read_bytes()


def test_a_shot_folder_copied_with_new_mtimes_is_still_usdcrowds(shot_copy, tmp_path, capsys):
    """``cp -r`` gives every file a new mtime: the copy's camera layer is known by its content and replaced
    without --force; an edit made in the copy is still the user's and kept."""
    import shutil

    copy = tmp_path / "copy"
    shutil.copytree(shot_copy, copy, copy_function=shutil.copy)     # content, not times
    cams = copy / "cameras.usda"
    assert cams.stat().st_mtime_ns != (shot_copy / "cameras.usda").stat().st_mtime_ns
    assert main(["cameras", str(copy / "shot.usda"), "--count", "1", "--no-progress"]) == 0
    text = cams.read_text()
    cams.write_text(text.replace("usdcrowd cameras", "usdcrowd Cameras", 1))   # the same size: read it
    before = cams.read_bytes()
    capsys.readouterr()
    assert main(["cameras", str(copy / "shot.usda"), "--count", "1", "--no-progress"]) == 2
    one_line_error(capsys, "cameras.usda", "changed since usdcrowd wrote it")
    assert cams.read_bytes() == before


def test_a_folder_of_one_kind_is_refused_for_another(shot_copy, tmp_path, capsys):
    before = digest_tree(shot_copy)
    capsys.readouterr()
    assert main(["metrics", str(shot_copy / "shot.usda"), "-o", str(shot_copy), "--no-progress"]) == 2
    one_line_error(capsys, "holds a shot's outputs, not a metrics's")
    assert digest_tree(shot_copy) == before


# ------------------------------------------------------------------ one writer per output folder
def _hold_lock(folder: Path) -> subprocess.Popen:
    """Another process holding the folder's lock, as a running usdcrowd command does."""
    code = ("import fcntl, os, sys, time; from pathlib import Path; d = Path(sys.argv[1]) / '.usdcrowd'; "
            "d.mkdir(parents=True, exist_ok=True); f = open(d / 'lock', 'a+'); "
            "fcntl.flock(f, fcntl.LOCK_EX); f.truncate(0); f.write(str(os.getpid())); f.flush(); "
            "print('held', flush=True); time.sleep(60)")
    proc = subprocess.Popen([sys.executable, "-c", code, str(folder)], stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "held"
    return proc


@pytest.mark.parametrize("command", ["simulate", "cameras", "frame", "metrics", "render", "preview", "dataset"])
def test_a_folder_another_run_writes_in_is_refused_at_once(museum_shot, shot_copy, tmp_path, capsys, command):
    scenario, _ = museum_shot
    out = shot_copy if command in ("simulate", "cameras", "frame") else tmp_path / "out"
    out.mkdir(exist_ok=True)
    from tests.helpers.datasets import write_spec

    spec = write_spec(tmp_path)
    argv = {"simulate": ["simulate", str(scenario), "-o", str(out), "--frames", "1:6"],
            "cameras": ["cameras", str(shot_copy / "shot.usda")],
            "frame": ["frame", str(shot_copy / "shot.usda"), "--behavior", "orbit", "--targets", "auto"],
            "metrics": ["metrics", str(shot_copy / "shot.usda"), "-o", str(out)],
            "render": ["render", str(shot_copy / "shot.usda"), "-o", str(out), "--preset", "preview"],
            "preview": ["preview", str(shot_copy / "shot.usda"), "-o", str(out)],
            "dataset": ["dataset", str(spec), "-o", str(out)]}[command]
    before = digest_tree(out)
    holder = _hold_lock(out)
    try:
        capsys.readouterr()
        t0 = time.monotonic()
        assert main(argv + ["--no-progress"]) == 2
        assert time.monotonic() - t0 < 10
        one_line_error(capsys, "another usdcrowd run", f"pid {holder.pid}", out.name)
    finally:
        holder.kill()
        holder.wait()
    assert digest_tree(out) == before


def test_two_simulate_runs_at_once_leave_one_whole_shot(museum_shot, tmp_path):
    """Real concurrent processes: the second is refused at once, the first's shot is whole."""
    scenario = tmp_path / "crowded.usda"
    assert main(["new", "museum", "-o", str(scenario), "--agents", "150"]) == 0
    out = tmp_path / "shot"
    argv = USDCROWD + ["simulate", str(scenario), "-o", str(out), "--no-progress"]
    first = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    lock = out / ".usdcrowd" / "lock"
    deadline = time.monotonic() + 60
    while not (lock.exists() and lock.read_text().strip()) and time.monotonic() < deadline:
        time.sleep(0.05)
    second = subprocess.run(argv, capture_output=True, text=True, timeout=120)
    assert first.poll() is None, "the first run ended before the second started: no overlap was tested"
    out1, err1 = first.communicate(timeout=300)
    assert first.returncode == 0, err1
    assert second.returncode == 2, second.stderr
    assert "another usdcrowd run" in second.stderr and len(second.stderr.splitlines()) == 1
    assert main(["validate", str(out / "shot.usda")]) == 0
    leftovers = [p.name for p in out.iterdir() if ".partial-" in p.name]
    assert not leftovers


def test_inspect_into_a_pipe_closed_early_exits_quietly(museum_shot):
    """`usdcrowd inspect shot.usda | head -1`: the reader is gone before the summary is written."""
    _, shot = museum_shot
    proc = subprocess.Popen(USDCROWD + ["inspect", str(shot / "shot.usda")], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    proc.stdout.close()
    err = proc.stderr.read()
    assert proc.wait(timeout=120) == 0 and err == "", err


@pytest.mark.parametrize("name", ["out.gif", "frames.png"])
def test_preview_refuses_an_output_it_cannot_write_as_named(museum_shot, tmp_path, capsys, name):
    """`preview -o out.gif` made a folder of PNGs named out.gif."""
    _, shot = museum_shot
    capsys.readouterr()
    assert main(["preview", str(shot / "shot.usda"), "-o", str(tmp_path / name), "--no-progress"]) == 2
    one_line_error(capsys, name, "MP4", "folder of PNG frames")
    assert not (tmp_path / name).exists()


def test_a_single_file_may_not_replace_what_another_command_wrote_in_its_folder(shot_copy, capsys):
    """`new -o shot/shot.usda` would replace the shot's entry layer with a scenario."""
    before = digest_tree(shot_copy)
    capsys.readouterr()
    assert main(["new", "museum", "-o", str(shot_copy / "shot.usda"), "--agents", "6"]) == 2
    one_line_error(capsys, "shot.usda", "usdcrowd simulate wrote")
    assert main(["new", "museum", "-o", str(shot_copy / "shot.usda"), "--agents", "6", "--force"]) == 2
    assert digest_tree(shot_copy) == before


def test_force_replaces_only_the_file_the_user_named(shot_copy, tmp_path, capsys):
    """preview -o p.mp4 --force: the default sheet p_sheet.png is not the user's to lose."""
    pytest.importorskip("imageio_ffmpeg")
    sheet = tmp_path / "p_sheet.png"
    sheet.write_bytes(b"my own picture")
    capsys.readouterr()
    assert main(["preview", str(shot_copy / "shot.usda"), "-o", str(tmp_path / "p.mp4"), "--frames", "1:2",
                 "--resolution", "64x36", "--force", "--no-progress"]) == 2
    one_line_error(capsys, "p_sheet.png", "not written by usdcrowd")
    assert sheet.read_bytes() == b"my own picture"


def test_the_images_a_scenario_uses_are_inputs_too(tmp_path, capsys):
    """A behavior map (an asset attribute, not a layer) is never written over."""
    scenario = tmp_path / "harbour.usda"
    assert main(["new", "harbour", "-o", str(scenario), "--agents", "6"]) == 0
    water = tmp_path / "maps" / "harbour_water.png"
    before = water.read_bytes()
    capsys.readouterr()
    assert main(["preview", str(scenario), "-o", str(tmp_path / "p"), "--sheet", str(water), "--no-progress"]) == 2
    one_line_error(capsys, "would overwrite an input", "harbour_water.png")
    assert water.read_bytes() == before


def test_a_folder_inside_one_another_run_writes_is_refused(museum_shot, tmp_path, capsys):
    scenario, _ = museum_shot
    ds = tmp_path / "ds"
    ds.mkdir()
    holder = _hold_lock(ds)
    try:
        capsys.readouterr()
        assert main(["simulate", str(scenario), "-o", str(ds / "sequences" / "mine"), "--frames", "1:6",
                     "--no-progress"]) == 2
        one_line_error(capsys, "another usdcrowd run", str(ds))
    finally:
        holder.kill()
        holder.wait()
    assert not (ds / "sequences").exists()


def test_a_shot_whose_scenario_changed_is_reported_by_every_reader(museum_shot, tmp_path, capsys):
    scenario, _ = museum_shot
    own = tmp_path / "museum.usda"
    own.write_bytes(scenario.read_bytes())
    shot = tmp_path / "shot"
    assert main(["simulate", str(own), "-o", str(shot), "--frames", "1:6", "--no-progress"]) == 0
    capsys.readouterr()
    assert main(["validate", str(shot / "shot.usda")]) == 0
    assert "warning" not in capsys.readouterr().err           # unchanged: nothing said
    os.utime(own, ns=(1, 1))                                  # touched, not changed: its bytes decide
    assert main(["validate", str(shot / "shot.usda")]) == 0
    assert "warning" not in capsys.readouterr().err
    own.write_text(own.read_text().replace("uniform float crowd:height = 1.", "uniform float crowd:height = 1.0", 1))
    for argv in (["validate", str(shot / "shot.usda")],
                 ["cameras", str(shot / "shot.usda"), "--count", "1", "--no-progress"],
                 ["preview", str(shot / "shot.usda"), "-o", str(tmp_path / "p"), "--frames", "1",
                  "--resolution", "32x18", "--no-progress"]):
        main(argv)
        err = capsys.readouterr().err
        assert "changed since the shot was simulated" in err and "museum.usda" in err, (argv, err)


def test_a_rolled_back_or_killed_write_stays_usdcrowds(tmp_path):
    """Versions put back by a rollback, or left by a kill between rename and record, are still usdcrowd's."""
    from usdcrowd import guard
    from usdcrowd.atomic import atomic_path, restored_on_failure

    out = tmp_path / "out"
    with guard.session(command="test"):
        from usdcrowd.atomic import output_dir

        output_dir(out, "test")
        with atomic_path(out / "a.txt") as tmp:
            tmp.write_text("first")
        with pytest.raises(KeyboardInterrupt), restored_on_failure([out / "a.txt"]):
            with atomic_path(out / "a.txt") as tmp:
                tmp.write_text("second, longer")
            raise KeyboardInterrupt
        assert (out / "a.txt").read_text() == "first"
        # Killed after the record, before the rename: the old bytes are still known.
        pending = out / ".a.partial-0123abcd.txt"
        pending.write_text("third version")
        guard.will_write(pending, out / "a.txt")
    with guard.session(command="test") as s:
        assert s.owns(out.resolve(), "a.txt")
    os.replace(pending, out / "a.txt")               # ... or killed after the rename, before its own record
    with guard.session(command="test") as s:
        output_dir(out, "test")
        assert s.owns(out.resolve(), "a.txt")
        (out / "a.txt").write_text("edited by hand")
        assert not s.owns(out.resolve(), "a.txt")


def test_an_empty_folder_is_nobodys_and_a_busy_inner_folder_is_refused(museum_shot, shot_copy, capsys):
    scenario, _ = museum_shot
    (shot_copy / "render").mkdir()                    # a render stopped before its first frame
    assert main(["simulate", str(scenario), "-o", str(shot_copy), "--frames", "1:6", "--no-progress"]) == 0
    holder = _hold_lock(shot_copy / "render")         # a render running into shot/render
    try:
        capsys.readouterr()
        assert main(["simulate", str(scenario), "-o", str(shot_copy), "--frames", "1:6", "--no-progress"]) == 2
        one_line_error(capsys, "another usdcrowd run is writing in", "render")
        assert main(["cameras", str(shot_copy / "shot.usda"), "--count", "1", "--no-progress"]) == 2
        one_line_error(capsys, "another usdcrowd run is writing in")
    finally:
        holder.kill()
        holder.wait()


def test_a_shot_made_before_records_is_adopted_only_when_forced(museum_shot, shot_copy, capsys):
    import shutil

    scenario, _ = museum_shot
    shutil.rmtree(shot_copy / ".usdcrowd")          # as a shot written by an earlier usdcrowd
    (shot_copy / "notes.txt").write_text("mine")
    capsys.readouterr()
    assert main(["simulate", str(scenario), "-o", str(shot_copy), "--frames", "1:6", "--no-progress"]) == 2
    one_line_error(capsys, "made before usdcrowd kept a record", "--force")
    assert main(["simulate", str(scenario), "-o", str(shot_copy), "--frames", "1:6", "--no-progress",
                 "--force"]) == 0
    assert "endTimeCode = 6" in (shot_copy / "shot.usda").read_text()
    assert (shot_copy / "notes.txt").read_text() == "mine"
    assert "notes.txt" not in (shot_copy / ".usdcrowd" / "written").read_text()     # adopted: usdcrowd's names only


def test_dataset_never_writes_over_its_spec(tmp_path, capsys):
    """The spec inside the folder the dataset is asked to fill: refused, the spec unchanged."""
    from tests.helpers.datasets import write_spec

    ds = tmp_path / "ds"
    ds.mkdir()
    spec = write_spec(ds, name="mine.toml")
    before = spec.read_bytes()
    capsys.readouterr()
    assert main(["dataset", str(spec), "-o", str(ds), "--no-progress"]) == 2
    one_line_error(capsys, "did not write", "mine.toml")
    assert spec.read_bytes() == before and sorted(p.name for p in ds.iterdir()) == ["mine.toml"]
    assert main(["dataset", str(spec), "-o", str(ds / "mine.toml"), "--no-progress"]) == 2
    one_line_error(capsys, "would overwrite an input")
    assert spec.read_bytes() == before
