"""UsdLux lights -> Mitsuba emitters, with one documented radiometric mapping.

Mitsuba is unit-less; we read UsdLux values as radiometric quantities in the
same arbitrary unit, the way Hydra's path tracers do. With
``I = inputs:intensity * 2 ** inputs:exposure`` and ``c`` the linear colour
times the colour-temperature tint (both from :class:`ShotScene.Light`):

- SphereLight, RectLight, DiskLight, CylinderLight: emitted radiance
  ``L = I * c`` on the light's surface (``area`` emitter on a mesh; on
  Mitsuba's analytic ``sphere`` for a SphereLight whose transform scales
  evenly, which samples the cone the sphere subtends instead of its whole
  area); with ``inputs:normalize`` the radiance is divided by the surface
  area, so the power no longer depends on the size (UsdLux's definition).
- DistantLight: irradiance on a surface facing the light ``E = I * c``
  with ``inputs:normalize`` on; unnormalised, UsdLux makes ``I`` the disc's
  luminance, so ``E`` is that times the disc's size factor (read once, in
  :func:`usdcrowd.core.shading.distant_illuminance`).
  With ``inputs:angle`` (its angular diameter, 0.53 degrees for the sun by
  default) it is a disc of that angular size far away (``area`` emitter on
  a 16-gon of the disc's area DISTANT_DISC_DISTANCE metres off, radiance
  ``E`` over the disc's solid angle), so shadows get the penumbra the angle
  gives; with angle 0, Mitsuba's ``directional`` emitter (hard shadows).
- DomeLight: radiance ``L = I * c`` from every direction (``constant``), or
  the latitude-longitude texture times ``I * c`` (``envmap``). A
  DomeLight's top pole is its +Y axis whatever the stage's up axis (UsdLux:
  the OpenEXR lat-long convention, longitude pi / 2 toward +X); a
  DomeLight_1's is its ``poleAxis`` ("scene", the default: the stage's up
  axis). Checked against Blender Cycles importing the same stage.

Light shapes are visible to the camera, and in the id pass each carries its
own id (:func:`light_id`: LIGHT_ID_BASE plus its index among the shot's
lights), named in the id table like scenery.
"""

from __future__ import annotations

import numpy as np

from ...core.shading import LIGHT_ID_BASE
from ...scenario.shot_scene import Light
from .meshes import GTID_ATTRIBUTE, id_texture, make_mesh

# Far enough that the sun's direction varies by 0.06 degrees across a 10 m scene, near enough for float32.
DISTANT_DISC_DISTANCE = 1.0e4
# The sun's disc: a polygon of this many sides with the circle's area (see _distant_disc).
SUN_SIDES = 16
# Mitsuba's envmap has its pole on local +Y; a Z-up stage's dome has it on local +Z.
_Y_UP_TO_Z_UP = np.array([[1, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 0], [0, 0, 0, 1]], dtype=np.float64)


def light_id(k: int) -> int:
    """Id-pass id of the shot's ``k``-th light's shape."""
    return LIGHT_ID_BASE + int(k)


def has_shape(light: Light) -> bool:
    """Sphere, rect, disk and cylinder lights are surfaces a camera sees; distant and dome lights are not."""
    return light.kind not in ("distant", "dome")


def is_uniform_sky(light: Light) -> bool:
    """A DomeLight without a texture: Mitsuba's ``constant`` emitter, which the path tracer gives no shadow rays."""
    return light.kind == "dome" and not light.texture


def _area(light: Light) -> float:
    return {"sphere": 4 * np.pi * light.radius ** 2, "rect": light.width * light.height,
            "disk": np.pi * light.radius ** 2, "cylinder": 2 * np.pi * light.radius * light.length}.get(light.kind, 1.0)


def emitted(light: Light) -> np.ndarray:
    """(3,) linear RGB radiance (area and dome lights) or irradiance (distant light)."""
    value = np.asarray(light.rgb, dtype=np.float64) * light.intensity
    if light.normalize and light.kind in ("sphere", "rect", "disk", "cylinder"):
        value = value / max(_area(light), 1e-12)
    return np.clip(value, 0.0, None)


def _light_geometry(light: Light):
    """(vertices (v, 3), faces (f, 3), normals (v, 3) or None) in the light's local space; emits toward -Z."""
    import trimesh

    if light.kind == "sphere":
        t = trimesh.creation.icosphere(subdivisions=3, radius=max(light.radius, 1e-3))
        return np.asarray(t.vertices), np.asarray(t.faces), np.asarray(t.vertex_normals)
    if light.kind == "cylinder":
        t = trimesh.creation.cylinder(radius=max(light.radius, 1e-3), height=max(light.length, 1e-3), sections=24)
        t.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, (0, 1, 0)))   # UsdLux: along X
        return np.asarray(t.vertices), np.asarray(t.faces), None
    if light.kind == "rect":
        w, h = light.width / 2, light.height / 2
        v = np.array([[-w, -h, 0], [w, -h, 0], [w, h, 0], [-w, h, 0]], dtype=np.float64)
        return v, np.array([[0, 2, 1], [0, 3, 2]]), None              # wound to face -Z
    if light.kind == "disk":
        a = np.linspace(0, 2 * np.pi, 33)[:-1]
        v = np.vstack([[0, 0, 0], np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], -1) * light.radius])
        k = np.arange(1, 33)
        return v, np.stack([np.zeros_like(k), np.roll(k, -1), k], -1), None           # faces -Z
    raise ValueError(light.kind)


def _distant_disc(key: str, k: int, direction: np.ndarray, angle: float, irradiance: np.ndarray):
    """A disc of angular diameter ``angle`` (radians) far along ``-direction`` whose irradiance is ``irradiance``.

    Radiance L over the disc's solid angle 2 pi (1 - cos(angle / 2)) gives the
    irradiance E on a surface facing it: L = E / (pi sin^2(angle / 2)). The
    disc is a SUN_SIDES-gon of the circle's area. Measured on the museum
    frame (64 spp): a 64-gon's shadow rays took 0.3 s more than Mitsuba's
    analytic disk (each picks a triangle by binary search), but with the
    analytic disk in the scene each frame's BVH rebuild took 0.43 s instead
    of 0.18 (the cause is inside Mitsuba and Embree); a 16-gon costs the
    least in all.
    """
    import mitsuba as mi

    half = 0.5 * angle
    n = SUN_SIDES
    radius = DISTANT_DISC_DISTANCE * np.tan(half) * np.sqrt(2 * np.pi / (n * np.sin(2 * np.pi / n)))
    radiance = irradiance / (np.pi * np.sin(half) ** 2)
    a = np.linspace(0, 2 * np.pi, n + 1)[:-1]
    disc = np.vstack([[0, 0, 0], np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], -1) * radius])
    idx = np.arange(1, n + 1)
    faces = np.stack([np.zeros_like(idx), idx, np.roll(idx, -1)], -1)      # faces +Z (toward the scene below)
    z = -direction                                                          # from the scene toward the light
    x = np.cross([0.0, 0.0, 1.0] if abs(z[2]) < 0.9 else [1.0, 0.0, 0.0], z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    world = (disc @ np.stack([x, y, z])) + z * DISTANT_DISC_DISTANCE
    # Faces must face the scene: the disc's normal is its local +Z mapped to -z (toward the scene).
    return make_mesh(key, world, faces[:, ::-1], 0, bsdf=mi.load_dict(_black()),
                     emitter=mi.load_dict(_area_emitter(radiance)))


def _area_emitter(radiance) -> dict:
    """Mitsuba's ``area`` emitter of (3,) linear RGB radiance."""
    return {"type": "area", "radiance": {"type": "rgb", "value": np.asarray(radiance, float).tolist()}}


def _black() -> dict:
    """A light's surface reflects nothing (Mitsuba would give it a diffuse BSDF)."""
    return {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0, 0.0, 0.0]}}


def _even_scale(m3: np.ndarray) -> float | None:
    """The scale of a rotation times an even scale (what Mitsuba's sphere allows), else None.

    1e-4 lets through rotations written with six digits (usda's 0.707107).
    """
    sv = np.linalg.svd(np.asarray(m3, float), compute_uv=False)
    return float(sv[0]) if sv[-1] > 0 and sv[0] - sv[-1] <= 1e-4 * sv[0] else None


def emitters(lights: list[Light], up_axis: str = "Z") -> dict:
    """Scene-dict entries (name -> Mitsuba dict or object) for every light.

    Parameters
    ----------
    lights : list of Light
    up_axis : str
        The stage's up axis ("Y" or "Z"): a dome's pole in its local space.

    Returns
    -------
    dict
        Emitters for dome lights and for distant lights without an angle;
        ``area`` emitters on a mesh (a distant light's disc, rect, disk and
        cylinder lights) or on Mitsuba's analytic sphere (sphere lights).
        Keys are ``light_<k>``.
    """
    import mitsuba as mi

    out = {}
    for k, light in enumerate(lights):
        value = emitted(light).tolist()
        key = f"light_{k}"
        if light.kind == "distant":
            direction = -light.to_world[2, :3]          # lights shine along their local -Z
            direction = direction / np.linalg.norm(direction)
            if light.angle > 0:
                out[key] = _distant_disc(key, k, direction, np.radians(light.angle), np.asarray(value))
            else:
                out[key] = {"type": "directional", "direction": direction.tolist(),
                            "irradiance": {"type": "rgb", "value": value}}
        elif light.kind == "dome":
            if not is_uniform_sky(light):
                bmp = np.array(mi.Bitmap(light.texture).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32,
                                                                srgb_gamma=False))
                local = _Y_UP_TO_Z_UP if light.pole_axis == "Z" else np.eye(4)
                m = (local @ light.to_world).T
                out[key] = {"type": "envmap", "bitmap": mi.Bitmap((bmp * np.asarray(value, np.float32))
                                                                  .astype(np.float32)),
                            "to_world": mi.ScalarTransform4f(m.tolist())}
            else:
                out[key] = {"type": "constant", "radiance": {"type": "rgb", "value": value}}
        elif light.kind == "sphere" and (scale := _even_scale(light.to_world[:3, :3])) is not None:
            # Analytic: shadow rays sample the cone the sphere subtends (a mesh's area samples waste
            # the far half; the museum's frame took 10 % longer, with 14 % more noise).
            out[key] = {"type": "sphere", "center": light.to_world[3, :3].tolist(),
                        "radius": max(light.radius, 1e-3) * scale,
                        "emitter": _area_emitter(value), "bsdf": _black(), GTID_ATTRIBUTE: id_texture(light_id(k))}
        else:
            v, f, n = _light_geometry(light)
            world = v @ light.to_world[:3, :3] + light.to_world[3, :3]
            if n is not None:
                n = n @ light.to_world[:3, :3]
            out[key] = make_mesh(key, world, f, light_id(k), normals=n, bsdf=mi.load_dict(_black()),
                                 emitter=mi.load_dict(_area_emitter(value)))
    return out
