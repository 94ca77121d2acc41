"""Small helpers for writing Sdf specs (the crowd layer's and its agents' prims)."""

from __future__ import annotations

import functools

import numpy as np


@functools.cache
def _pxr_sdf():
    """pxr's Sdf, imported once: an import statement in the per-attribute helpers cost a part writer
    half a second (150,000 attributes)."""
    from pxr import Sdf

    return Sdf


def value_types():
    """Sdf.ValueTypeNames."""
    return _pxr_sdf().ValueTypeNames


def new_attribute(prim_spec, name, type_name, value=None, variability=None, custom=False):
    """An attribute spec on ``prim_spec`` (varying unless told), with its default ``value`` if given."""
    Sdf = _pxr_sdf()
    spec = Sdf.AttributeSpec(prim_spec, name, type_name,
                             variability or Sdf.VariabilityVarying, custom)
    if value is not None:
        spec.default = value
    return spec


def new_prim(layer, path, type_name="", specifier=None):
    """The prim spec at ``path`` (its ancestors as overs), an ``over`` unless ``specifier`` says."""
    Sdf = _pxr_sdf()
    spec = Sdf.CreatePrimInLayer(layer, path)
    spec.specifier = specifier if specifier is not None else Sdf.SpecifierOver
    if type_name:
        spec.typeName = type_name
    return spec


def set_palette(body_spec, palette: np.ndarray) -> None:
    """A body's displayColor rows: (r, 3) linear RGB, indexed per vertex by the prototype."""
    from pxr import Vt

    spec = new_attribute(body_spec, "primvars:displayColor", value_types().Color3fArray,
                 Vt.Vec3fArray.FromNumpy(np.asarray(palette, dtype=np.float32)))
    spec.SetInfo("interpolation", "vertex")
