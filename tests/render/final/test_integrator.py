"""The beauty's path tracer (a shadow ray to every light) converges to what Mitsuba's own does, with less noise."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("mitsuba")

from usdcrowd.render.final import integrator  # noqa: E402
from usdcrowd.render.final.frame import FrameRenderer  # noqa: E402

W, H = 128, 72
FRAME = 6
SPP = 256


def relative_mse(x, ref):
    return float(np.mean((x - ref) ** 2 / (ref ** 2 + 1e-2)))


def _frames(shot, mitsuba_path: bool, monkeypatch, seeds) -> list[np.ndarray]:
    monkeypatch.setattr(integrator, "MAX_LIGHTS", -1 if mitsuba_path else 4)
    out = []
    for seed in seeds:
        r = FrameRenderer(shot, None, (W, H), spp=SPP, max_depth=4, ground_truth=False, sampler="independent",
                          seed=seed)
        assert (type(r.built.scene.integrator()).__name__ == "AllLightsPath") != mitsuba_path
        out.append(r.render(FRAME).beauty.astype(np.float64))
    return out


def test_every_light_path_tracer_converges_to_mitsubas_with_less_noise(walking_museum, monkeypatch):
    """The museum's sun, sky and lamp, two independent frames from each tracer.

    A frame's noise is half the relative MSE between two frames of other
    seeds. Unbiased, the two tracers' mean frames differ by their noise only;
    ours has at most half the noise of Mitsuba's at the same samples.
    """
    o1, o2 = _frames(walking_museum, False, monkeypatch, (1, 2))
    t1, t2 = _frames(walking_museum, True, monkeypatch, (3, 4))
    noise_ours, noise_theirs = relative_mse(o1, o2) / 2, relative_mse(t1, t2) / 2
    ours, theirs = (o1 + o2) / 2, (t1 + t2) / 2
    expected = (noise_ours + noise_theirs) / 2          # each mean frame has half its frames' noise
    assert relative_mse(ours, theirs) < 1.5 * expected, (relative_mse(ours, theirs), expected)
    assert ours.mean() == pytest.approx(theirs.mean(), rel=2e-3)
    assert noise_ours * 2 < noise_theirs, (noise_ours, noise_theirs)


def _cutout_and_metal_scene(mi, integrator_type: str, sky: str = "constant") -> dict:
    """A metal floor (no diffuse lobe) seen through a half-opaque cut-out card, and a two-sided card seen
    from behind, lit by a sky and a lamp. The sky is uniform (``constant``: no shadow rays) or a texture
    with a bright patch (``envmap``: shadow rays, importance-sampled)."""
    if sky == "envmap":
        texels = np.full((16, 32, 3), 0.4, dtype=np.float32)
        texels[3:5, 20:23] = 40.0
        sky_dict = {"type": "envmap", "bitmap": mi.Bitmap(texels)}
    else:
        sky_dict = {"type": "constant", "radiance": {"type": "rgb", "value": 0.6}}
    def rect(to_world, bsdf):
        return {"type": "rectangle", "to_world": to_world, "bsdf": bsdf}

    T = mi.ScalarTransform4f
    return {
        "type": "scene",
        "integrator": {"type": integrator_type, "max_depth": 4},
        "sensor": {"type": "perspective", "fov": 50,
                   "to_world": T().look_at(origin=[0, 1.5, 4], target=[0, 0, 0], up=[0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": 48, "height": 36, "rfilter": {"type": "box"},
                            "pixel_format": "rgb"},
                   "sampler": {"type": "independent"}},
        "floor": rect(T().rotate([1, 0, 0], -90).scale(3),
                      {"type": "principled", "base_color": {"type": "rgb", "value": [0.9, 0.7, 0.5]},
                       "metallic": 1.0, "roughness": 0.5}),
        "card": rect(T().translate([0, 0.8, 1.5]).scale(0.8),
                     {"type": "mask", "opacity": {"type": "rgb", "value": [0.5, 0.5, 0.5]},
                      "bsdf": {"type": "principled", "base_color": {"type": "rgb", "value": [0.2, 0.6, 0.3]},
                               "roughness": 0.6}}),
        "back": rect(T().translate([-1.4, 0.9, 0.5]).rotate([0, 1, 0], 180).scale(0.6),
                     {"type": "twosided", "bsdf": {"type": "principled", "roughness": 0.4,
                                                   "base_color": {"type": "rgb", "value": [0.8, 0.3, 0.3]}}}),
        "wall": rect(T().translate([0, 1, -2]).scale(3),
                     {"type": "principled", "base_color": {"type": "rgb", "value": [0.7, 0.7, 0.7]},
                      "roughness": 0.5}),
        "sky": sky_dict,
        "lamp": {"type": "sphere", "center": [1, 2.5, -0.5], "radius": 0.5,
                 "emitter": {"type": "area", "radiance": {"type": "rgb", "value": 6.0}}},
    }


@pytest.mark.parametrize("sky", ["constant", "envmap"])
def test_the_mixed_bounce_sampling_is_unbiased_on_metal_and_cut_outs(sky):
    """No diffuse lobe for the cosine directions to find, a cut-out's pass-through (a null component
    drawn only by the BSDF's share of bounces), and a back face that reflects: all still converge to
    Mitsuba's picture, under a uniform sky (bounces only) and under a textured one (shadow rays too)."""
    from usdcrowd.render.final import variant

    mi = variant.activate(variant.choose_variant(None))
    if mi.variant().startswith("scalar"):
        pytest.skip("the every-light tracer runs on the JIT variants only")
    integrator.register()
    frames = {}
    for name, seeds in ((integrator.NAME, range(1, 7)), ("path", range(7, 13))):   # seeds apart: independent
        scene = mi.load_dict(_cutout_and_metal_scene(mi, name, sky))
        frames[name] = np.stack([np.array(mi.render(scene, spp=SPP, seed=seed), dtype=np.float64)
                                 for seed in seeds])
    ours, theirs = frames[integrator.NAME], frames["path"]
    # Each mean frame's noise: the per-pixel variance over its 6 frames, over 6 (weighted as relative_mse).
    both = (ours.mean(0) + theirs.mean(0)) / 2
    expected = float(np.mean((ours.var(0, ddof=1) + theirs.var(0, ddof=1)) / 6 / (both ** 2 + 1e-2)))
    assert relative_mse(ours.mean(0), theirs.mean(0)) < 1.5 * expected, (relative_mse(ours.mean(0), theirs.mean(0)),
                                                                         expected)
    # The picture's level, within 4 standard errors of the seeds' spread.
    level_o, level_t = ours.mean((1, 2, 3)), theirs.mean((1, 2, 3))
    error = np.sqrt(level_o.var(ddof=1) / 6 + level_t.var(ddof=1) / 6)
    assert abs(level_o.mean() - level_t.mean()) < 4 * error, (level_o.mean(), level_t.mean(), error)


def test_cosine_bounces_take_noise_out_of_the_museum(walking_museum):
    """Against the BSDF's own sampling alone (share 0), the mixture has at least 1.3 times less noise."""
    from usdcrowd.render.final import variant

    r = FrameRenderer(walking_museum, None, (W, H), spp=64, max_depth=4, ground_truth=False)
    mi = variant.activate(r.variant)
    if type(r.built.scene.integrator()).__name__ != "AllLightsPath":
        pytest.skip("the every-light tracer runs on the JIT variants only")
    r.render(FRAME)
    noise = {}
    for share in (0.0, integrator.DIFFUSE_SHARE):
        tracer = mi.load_dict({"type": integrator.NAME, "max_depth": 4, "diffuse_share": share})
        a, b = (r._film(mi, seed, 64, tracer)[..., :3].astype(np.float64) for seed in (1, 2))
        noise[share] = relative_mse(a, b) / 2
    assert noise[integrator.DIFFUSE_SHARE] * 1.3 < noise[0.0], noise
