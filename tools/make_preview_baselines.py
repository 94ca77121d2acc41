"""Write the preview's reference images: tests/baselines/preview_*.png.

    .venv/bin/python tools/make_preview_baselines.py

Builds a tiny shot (a floor, a block, a sun and sky, one camera, four agents
walking straight; nothing random that the simulation could change) and
renders it headless. tests/render/preview/test_preview.py builds the same
shot with the functions here and compares its render with these files; re-run
this after a deliberate change to the preview's look, and look at the images
first.
"""

from __future__ import annotations

import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BASELINES = ROOT / "tests" / "baselines"
SIZE = (320, 180)
TIME = 4.0
CAMERA = "/World/Cam"
# File name -> level of detail on (characters ~50 px tall: the clustered
# mesh) or off (the full mesh).
BASELINE_NAMES = {"preview_tiny.png": True, "preview_tiny_full.png": False}

TINY_STAGE = textwrap.dedent('''\
    #usda 1.0
    (
        defaultPrim = "World"
        metersPerUnit = 1
        upAxis = "Z"
        startTimeCode = 1
        endTimeCode = 6
        timeCodesPerSecond = 24
        customLayerData = { dictionary usdcrowd = { int seed = 7 } }
    )

    def Xform "World"
    {
        def Mesh "Floor"
        {
            int[] faceVertexCounts = [4]
            int[] faceVertexIndices = [0, 1, 2, 3]
            point3f[] points = [(-6, -6, 0), (6, -6, 0), (6, 6, 0), (-6, 6, 0)]
            color3f[] primvars:displayColor = [(0.5, 0.45, 0.4)]
        }

        def Cube "Block"
        {
            double size = 1
            color3f[] primvars:displayColor = [(0.2, 0.35, 0.6)]
            double3 xformOp:translate = (2.5, 1.5, 0.75)
            float3 xformOp:scale = (1.2, 1.2, 1.5)
            uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:scale"]
        }

        def DistantLight "Sun"
        {
            bool inputs:normalize = true
            float inputs:intensity = 3
            color3f inputs:color = (1, 0.96, 0.9)
            float3 xformOp:rotateXYZ = (35, 0, 40)
            uniform token[] xformOpOrder = ["xformOp:rotateXYZ"]
        }

        def DomeLight "Sky"
        {
            float inputs:intensity = 0.5
            color3f inputs:color = (0.75, 0.85, 1)
        }

        def Camera "Cam"
        {
            float focalLength = 0.24
            float horizontalAperture = 0.36
            float verticalAperture = 0.2025
            float2 clippingRange = (0.1, 100)
            double3 xformOp:translate = (0, -9, 4.5)
            float3 xformOp:rotateXYZ = (68, 0, 0)
            uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateXYZ"]
        }

        def CrowdGroup "People"
        {
            uniform token crowd:behavior = "walk"
            uniform token crowd:condition = "isolated"

            def SkelRoot "A" (prepend apiSchemas = ["CrowdAgentAPI"])
            {
                uniform int crowd:agentId = 1
                uniform color3f crowd:color = (0.7, 0.15, 0.1)
                uniform float crowd:speed = 1.2
                uniform point3f crowd:startPosition = (-2, 0, 0)
            }
            def SkelRoot "B" (prepend apiSchemas = ["CrowdAgentAPI"])
            {
                uniform int crowd:agentId = 2
                uniform color3f crowd:color = (0.1, 0.5, 0.15)
                uniform float crowd:speed = 0.8
                uniform float crowd:height = 1.6
                uniform point3f crowd:startPosition = (0, -1.5, 0)
            }
            def SkelRoot "C" (prepend apiSchemas = ["CrowdAgentAPI"])
            {
                uniform int crowd:agentId = 7
                uniform color3f crowd:color = (0.85, 0.75, 0.2)
                uniform float crowd:speed = 1.0
                uniform float crowd:height = 1.9
                uniform point3f crowd:startPosition = (1, 3, 0)
            }
            def SkelRoot "D" (prepend apiSchemas = ["CrowdAgentAPI"])
            {
                uniform int crowd:agentId = 12
                uniform color3f crowd:color = (0.3, 0.3, 0.8)
                uniform float crowd:speed = 1.4
                uniform point3f crowd:startPosition = (-3.5, 2.5, 0)
            }
        }
    }
    ''')


def make_tiny_shot(out_dir, stage: str = TINY_STAGE) -> Path:
    """Write the tiny scenario (or another ``stage`` text) and its shot (agents walk straight) into
    ``out_dir``; returns shot.usda."""
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))           # the repository's tests package
    from tests.helpers.frames import straight_walk

    import usdcrowd  # noqa: F401  (registers the schemas)
    from usdcrowd.jobs.pipeline import author_shot

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    scenario = out_dir / "tiny.usda"
    scenario.write_text(stage)
    r = author_shot(scenario, out_dir / "shot", lambda sc: [straight_walk(sc.agents, sc.time)], progress=False)
    return Path(r.shot)


def render_tiny(shot, lod_enabled: bool = True):
    """The frame the baseline holds: PreviewFrame of ``shot`` at TIME from CAMERA."""
    from usdcrowd.render.preview import LodSettings, PreviewRenderer

    r = PreviewRenderer(shot, *SIZE, lod_settings=LodSettings(enabled=lod_enabled))
    try:
        return r.render(TIME, CAMERA)
    finally:
        r.release()


def main() -> int:
    import tempfile

    from usdcrowd.render.preview.output import write_png

    BASELINES.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        shot = make_tiny_shot(tmp)
        for name, lod_enabled in BASELINE_NAMES.items():
            frame = render_tiny(shot, lod_enabled)
            print("wrote", write_png(frame.color, BASELINES / name))
    return 0


if __name__ == "__main__":
    sys.exit(main())
