"""Final frames with Mitsuba 3: physically based beauty and exact ground truth.

Modules, in the order a frame flows through them:

- :mod:`.variant`   which Mitsuba variant (cuda, llvm, scalar), probed safely;
- :mod:`.materials` UsdPreviewSurface -> principled BSDF;
- :mod:`.lights`    UsdLux -> emitters (the radiometric mapping);
- :mod:`.camera`    UsdGeom.Camera -> sensor, and the ground-truth pixel rays;
- :mod:`.meshes`    numpy -> ``mi.Mesh`` carrying ground-truth ids;
- :mod:`.build`     the shot -> one Mitsuba scene, once per sequence;
- :mod:`.frame`     per frame: update, beauty, ground-truth passes;
- :mod:`.exr`       the multi-channel EXR of a frame.

Mitsuba, Dr.Jit and OpenEXR are imported inside the functions that use them.
"""

from __future__ import annotations
