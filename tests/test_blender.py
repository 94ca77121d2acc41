"""Blender reads our shots as we mean them: its own USD importer (the ``bpy`` wheel, headless, no plugin path)."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest

pytestmark = pytest.mark.slow

BPY = ["bpy==5.0.1"]

# Imports each shot and prints every armature's root bone head in world space at some frames.
IMPORT_SCRIPT = '''
import json, sys
import bpy
out = {}
for path in sys.argv[2:]:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.usd_import(filepath=path)
    scene = bpy.context.scene
    arms = [o for o in bpy.data.objects if o.type == "ARMATURE"]
    frames = [int(f) for f in sys.argv[1].split(",")]
    roots = {}
    for f in frames:
        scene.frame_set(f)
        for o in arms:
            roots.setdefault(o.name, []).append(list((o.matrix_world @ o.pose.bones[0].matrix).translation))
    out[path] = {"range": [scene.frame_start, scene.frame_end], "roots": roots}
print("RESULT " + json.dumps(out))
'''


@pytest.fixture(scope="module")
def blender_python():
    from tool_venvs import tool_python

    return tool_python("bpy", BPY, "USDCROWD_BPY_VENV")


def _blender(python: str, tmp_path, frames: list[int], *shots) -> dict:
    script = tmp_path / "import_shots.py"
    script.write_text(IMPORT_SCRIPT)
    run = subprocess.run([python, str(script), ",".join(map(str, frames)), *map(str, shots)],
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    line = next(ln for ln in run.stdout.splitlines() if ln.startswith("RESULT "))
    return json.loads(line[len("RESULT "):])


def test_blender_plays_a_shot_split_in_value_clips_as_the_one_layer_shot(blender_python, museum_path, tmp_path):
    from frames_factory import straight_walk

    from usdcrowd.pipeline import author_shot
    from usdcrowd.scenario.crowd import read_crowd

    def walk(sc):
        yield straight_walk(sc.agents, sc.time)

    shots = {}
    for name, window in (("inline", None), ("clipped", 6)):
        shots[name] = author_shot(museum_path, tmp_path / name, walk, frames=(1, 20), progress=False,
                                  events=False, clip_frames=window).shot
    assert (tmp_path / "clipped" / "crowd.clips").is_dir()
    frames = [1, 6, 7, 13, 20]
    got = _blender(blender_python, tmp_path, frames, *shots.values())
    inline, clipped = (got[shots[k]] for k in ("inline", "clipped"))
    assert inline["range"] == clipped["range"] == [1, 20]
    assert inline["roots"].keys() == clipped["roots"].keys() and len(inline["roots"]) > 10
    np.testing.assert_array_equal(np.array(list(clipped["roots"].values())), np.array(list(inline["roots"].values())))
    # And Blender's root bones follow the agents usdcrowd simulated (Blender names the armatures after the
    # Skeleton prims, so they are matched by position: one agent each, at every frame).
    # Invisible agents (the invisible leaders) are not imported.
    crowd, info = read_crowd(shots["clipped"])
    heads = np.array(list(clipped["roots"].values()))[:, :, :2]               # (armatures, frames, 2)
    walked = np.swapaxes(crowd.position[np.array(frames) - 1][:, info.visible, :2], 0, 1)  # (agents, frames, 2)
    gap = np.linalg.norm(heads[:, None] - walked[None], axis=-1).max(axis=2)  # worst frame, per pair
    match = gap.argmin(axis=1)
    assert len(set(match.tolist())) == len(heads) == len(walked)
    assert gap[np.arange(len(heads)), match].max() < 1e-4
