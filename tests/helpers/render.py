"""The analytic box stage of the final-render tests and how sharp its edge is."""

from __future__ import annotations

import numpy as np

from tests.helpers.shots import HEADER

# A 2 m cube whose front face is 9 m in front of a camera looking along +Y, lit by a uniform sky.
BOX_STAGE = '''
def Xform "World"
{
    def Cube "Box"
    {
        double size = 2
        color3f[] primvars:displayColor = [(0.5, 0.5, 0.5)]
        double3 xformOp:translate = (0, 10, 0)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }
    def DomeLight "Sky"
    {
        float inputs:intensity = 1
    }
    def Camera "Cam"
    {
        float focalLength = 0.24
        float horizontalAperture = 0.36
        float verticalAperture = 0.27
        float2 clippingRange = (0.1, 100)
        float3 xformOp:rotateXYZ = (90, 0, 0)
        uniform token[] xformOpOrder = ["xformOp:rotateXYZ"]
    }
}
'''


def edge_width(image: np.ndarray) -> float:
    """Width in pixels between 25 % and 75 % of the step across the box's left edge (rows averaged)."""
    x25, _, x75 = edge_crossings(image)
    return abs(x25 - x75)


def edge_crossings(image: np.ndarray) -> tuple[float, float, float]:
    """Sub-pixel columns where the step across the box's left edge passes 25, 50 and 75 % (rows averaged)."""
    lum = image.mean(-1)
    h, w = lum.shape
    row = lum[h // 3: 2 * h // 3].mean(0)
    inside, outside = np.median(row[w // 2 - 5: w // 2 + 5]), np.median(row[:8])
    p = (row[: w // 2] - inside) / (outside - inside)            # 1 in the sky, 0 on the box
    box = np.flatnonzero(p < 0.5)[0]                               # the box starts about here

    def crossing(level):
        """Sub-pixel position, left of the box's start, where the profile rises through ``level``."""
        j = box
        while j > 0 and p[j - 1] < level:
            j -= 1
        a, b = p[j], p[j - 1]                                      # inside side, outside side
        return j - (level - a) / (b - a)

    return crossing(0.25), crossing(0.5), crossing(0.75)


DOF_CAMERA = '''
        float focalLength = 1.0
        float horizontalAperture = 0.36
        float verticalAperture = 0.27
        float2 clippingRange = (0.1, 100)
        float fStop = {f_stop}
        float focusDistance = {focus}
'''


def dof_box_stage(folder, f_stop: float, focus: float):
    """The box stage seen through a 100 mm lens at ``f_stop``, focused at ``focus`` metres (its path)."""
    stage = BOX_STAGE.replace('''        float focalLength = 0.24
        float horizontalAperture = 0.36
        float verticalAperture = 0.27
        float2 clippingRange = (0.1, 100)
''', DOF_CAMERA.format(f_stop=f_stop, focus=focus))
    path = folder / "dof.usda"
    path.write_text(HEADER.format(up="Z", mpu=1, end=1) + stage)
    return path
