"""The crowd schemas: generated files current, registered, documented, with fallbacks."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest
from pxr import Sdf, Usd

from usdcrowd import schema
from usdcrowd.core.resources import data_dir

from tests.helpers.tools import load_tool

TYPED = (schema.GROUP, schema.BEHAVIOR_LAYER, schema.INTEREST_POINT, schema.EVENT)
APPLIED = (schema.AGENT_API, schema.CAMERA_AGENT_API, schema.SCENERY_API)


def test_generated_schema_files_are_current():
    regen_schemas = load_tool("regen_schemas")
    assert regen_schemas.stale_files() == [], "run python tools/regen_schemas.py"


@pytest.mark.parametrize("type_name", TYPED)
def test_typed_schemas_are_registered(type_name):
    stage = Usd.Stage.CreateInMemory()
    prim = stage.DefinePrim("/X", type_name)
    assert prim.IsA(Usd.Typed)
    assert Usd.SchemaRegistry().FindConcretePrimDefinition(type_name) is not None


@pytest.mark.parametrize("api", APPLIED)
def test_applied_schemas_are_registered(api):
    stage = Usd.Stage.CreateInMemory()
    prim = stage.DefinePrim("/X", "Camera")
    assert prim.ApplyAPI(api)
    assert prim.HasAPI(api)


def _definitions():
    reg = Usd.SchemaRegistry()
    for name in TYPED:
        yield name, reg.FindConcretePrimDefinition(name)
    for name in APPLIED:
        yield name, reg.FindAppliedAPIPrimDefinition(name)


def test_every_attribute_has_doc_fallback_and_tokens_have_allowed_tokens():
    source = Sdf.Layer.FindOrOpen(str(data_dir("schemas") / "schema.usda"))
    checked = 0
    for name, definition in _definitions():
        class_spec = source.GetPrimAtPath(f"/{name}")
        for prop in definition.GetPropertyNames():
            if not prop.startswith("crowd:"):
                continue
            spec = class_spec.properties[prop]
            assert spec.documentation.strip(), f"{name}.{prop} has no doc"
            if isinstance(spec, Sdf.AttributeSpec):
                if spec.typeName != Sdf.ValueTypeNames.Asset:
                    assert definition.GetAttributeFallbackValue(prop) is not None, f"{name}.{prop} has no fallback"
                if spec.typeName == Sdf.ValueTypeNames.Token:
                    assert spec.allowedTokens, f"{name}.{prop} has no allowedTokens"
                checked += 1
    assert checked > 50


def test_fallbacks_are_what_the_schema_documents():
    stage = Usd.Stage.CreateInMemory()
    g = stage.DefinePrim("/G", schema.GROUP)
    assert g.GetAttribute("crowd:personality").Get() == "random"
    assert g.GetAttribute("crowd:subclones").Get() == 1
    assert tuple(g.GetAttribute("crowd:speedRange").Get()) == pytest.approx((1.1, 1.5))
    cam = stage.DefinePrim("/C", "Camera")
    cam.ApplyAPI(schema.CAMERA_AGENT_API)
    assert cam.GetAttribute("crowd:camera:mode").Get() == "scouting"


def test_registration_works_with_a_users_own_plugin_path(tmp_path):
    # A user's PXR_PLUGINPATH_NAME must not hide our schemas.
    other = tmp_path / "their_plugins"
    other.mkdir()
    (other / "plugInfo.json").write_text('{"Plugins": []}')
    code = ("import usdcrowd; from pxr import Usd; s = Usd.Stage.CreateInMemory(); "
            "p = s.DefinePrim('/G', 'CrowdGroup'); print(p.IsA(Usd.Typed), p.GetAttribute('crowd:clones').Get())")
    env = dict(os.environ, PXR_PLUGINPATH_NAME=str(other))
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["True", "0"]
