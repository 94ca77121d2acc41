"""Small stages and shots the tests of several areas write: the .usda header, a Y-up centimetre stage,
a museum shot made by the command line."""

from __future__ import annotations

from pathlib import Path

HEADER = '''#usda 1.0
(
    defaultPrim = "World"
    metersPerUnit = {mpu}
    upAxis = "{up}"
    startTimeCode = 1
    endTimeCode = {end}
    timeCodesPerSecond = 24
)
'''

# A group of three walkers and a box in a Y-up, centimetre stage (write it with HEADER, up="Y", mpu=0.01).
Y_UP_CM = '''
def Xform "World"
{
    def CrowdGroup "Crowd"
    {
        uniform int crowd:clones = 3
        uniform point3f crowd:spawnCenter = (100, 0, -200)
        uniform float crowd:spawnRadius = 50
        def SkelRoot "Walker" (prepend apiSchemas = ["CrowdAgentAPI"])
        {
            uniform point3f crowd:startPosition = (300, 0, -400)
        }
    }
    def Cube "Box"
    {
        double size = 100
        double3 xformOp:translate = (0, 50, 500)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }
}
'''


def cli_museum_shot(folder: Path, agents: int, last_frame: int) -> tuple[Path, Path]:
    """A museum scenario and its shot made by the command line, so usdcrowd owns their files.

    Returns (scenario path, shot folder).
    """
    from usdcrowd.cli import main

    scenario = folder / "museum.usda"
    assert main(["new", "museum", "-o", str(scenario), "--agents", str(agents)]) == 0
    assert main(["simulate", str(scenario), "-o", str(folder / "shot"), "--frames", f"1:{last_frame}",
                 "--no-progress"]) == 0
    return scenario, folder / "shot"
