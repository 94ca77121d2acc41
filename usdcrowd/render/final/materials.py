"""UsdPreviewSurface (as :class:`~usdcrowd.scenario.shot_scene.Material`) -> Mitsuba BSDFs.

Mapping, input by input:

- ``diffuseColor`` -> ``principled.base_color`` (linear RGB, or a ``bitmap``
  texture; 8-bit textures are decoded from sRGB by Mitsuba);
- ``roughness`` -> ``principled.roughness`` (both are perceptual roughness,
  alpha = roughness**2);
- ``metallic`` -> ``principled.metallic``;
- the default specular of UsdPreviewSurface (ior 1.5, F0 = 0.04) is the
  principled BSDF's ``specular = 0.5`` (F0 = 0.08 * specular);
- ``opacity`` < 1 -> the BSDF wrapped in a ``mask`` (cut-out transparency;
  UsdPreviewSurface's opacity is coverage, not refraction).
"""

from __future__ import annotations

import numpy as np

from ...core.shading import Material

# Clothing of the characters: matte fabric.
AGENT_ROUGHNESS = 0.75


def bsdf_dict(material: Material) -> dict:
    """Mitsuba plugin dict for one material."""
    if material.base_color_texture:
        base = {"type": "bitmap", "filename": material.base_color_texture, "wrap_mode": "repeat"}
    else:
        base = {"type": "rgb", "value": np.clip(np.asarray(material.base_color, float), 0.0, 1.0).tolist()}
    bsdf = {"type": "principled", "base_color": base, "roughness": float(np.clip(material.roughness, 0.0, 1.0)),
            "metallic": float(np.clip(material.metallic, 0.0, 1.0)), "specular": 0.5}
    if material.opacity < 1.0:
        bsdf = {"type": "mask", "opacity": {"type": "rgb", "value": [float(max(material.opacity, 0.0))] * 3},
                "bsdf": bsdf}
    return bsdf


def agent_bsdf_dict(face_roughness: bool = False) -> dict:
    """Characters' BSDF: per-vertex colour from the mesh attribute ``vertex_color``.

    With ``face_roughness``, roughness per face too (mesh attribute ``face_roughness``,
    from the materials bound to the body's subsets); else :data:`AGENT_ROUGHNESS`.
    """
    rough = {"type": "mesh_attribute", "name": "face_roughness"} if face_roughness else AGENT_ROUGHNESS
    return {"type": "principled", "base_color": {"type": "mesh_attribute", "name": "vertex_color"},
            "roughness": rough, "metallic": 0.0, "specular": 0.5}


def usd_uv_to_mitsuba(uv: np.ndarray) -> np.ndarray:
    """(v, 2) USD ``st`` (origin at the image's bottom left) -> Mitsuba uv (origin at the top left)."""
    out = np.asarray(uv, dtype=np.float32).copy()
    out[:, 1] = 1.0 - out[:, 1]
    return out
