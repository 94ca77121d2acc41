"""Less noise per second (issue 14, point 1): the sampler chosen by measurement, and OIDN on the beauty."""

from __future__ import annotations

import numpy as np
import pytest

from usdcrowd.render.final.frame import FrameRenderer, sample_passes

from tests.helpers.paths import FAILURES

pytest.importorskip("mitsuba")
pytest.importorskip("pyoidn")

W, H = 128, 72
FRAME = 6


def relative_mse(x: np.ndarray, ref: np.ndarray) -> float:
    """Mean of (x - ref)^2 / (ref^2 + 0.01): the error measure of the render benchmark."""
    return float(np.mean((x - ref) ** 2 / (ref ** 2 + 1e-2)))


@pytest.fixture(scope="module")
def reference(walking_museum):
    """The frame at 1,024 spp (independent sampler, another seed): what the noisy frames converge to."""
    return FrameRenderer(walking_museum, None, (W, H), spp=1024, max_depth=4, ground_truth=False,
                         sampler="independent", seed=12345).render(FRAME).beauty


def _save_failure(name: str, *images):
    from PIL import Image

    out = FAILURES
    out.mkdir(exist_ok=True)
    strip = np.concatenate([np.clip(im, 0, 1) ** (1 / 2.2) for im in images], axis=1)
    Image.fromarray((strip * 255).astype(np.uint8)).save(out / f"{name}.png")
    return out / f"{name}.png"


def test_the_chosen_sampler_has_less_noise_than_independent_samples(walking_museum, reference):
    """Averaged over three seeds, multijitter's 16-spp frame is at least 1.5 times closer than independent's."""
    err = {}
    for sampler in ("independent", "multijitter"):
        err[sampler] = np.mean([relative_mse(FrameRenderer(walking_museum, None, (W, H), spp=16, max_depth=4,
                                                           ground_truth=False, sampler=sampler, seed=s)
                                             .render(FRAME).beauty, reference) for s in (1, 2, 3)])
    assert err["multijitter"] * 1.5 < err["independent"], err


def test_denoising_brings_a_16_spp_frame_half_as_close_again(walking_museum, reference):
    # The better the raw frame, the less the denoiser adds: 0.0067 -> 0.0019 with Mitsuba's one-light
    # path tracer, 0.0022 -> 0.0010 with a shadow ray to every light, 0.00078 -> 0.00041 with the
    # bounce mixture and analytic lights (render.final.integrator, .lights).
    noisy = FrameRenderer(walking_museum, None, (W, H), spp=16, max_depth=4, ground_truth=False, denoise=True, seed=1)
    r = noisy.render(FRAME)
    e_raw, e_den = relative_mse(r.raw, reference), relative_mse(r.beauty, reference)
    if not e_den * 1.5 < e_raw:
        where = _save_failure("denoise", r.raw, r.beauty, reference)
        pytest.fail(f"relative MSE raw {e_raw:.5f}, denoised {e_den:.5f}; raw, denoised, reference in {where}")
    # The picture's level is kept: mean within 3 % of the converged frame's.
    assert r.beauty.mean() == pytest.approx(reference.mean(), rel=0.03)


def test_denoising_leaves_the_ground_truth_exact(walking_museum):
    plain = FrameRenderer(walking_museum, None, (W, H), spp=4, max_depth=2).render(FRAME)
    den = FrameRenderer(walking_museum, None, (W, H), spp=4, max_depth=2, denoise=True).render(FRAME)
    assert plain.raw is None and den.raw is not None
    np.testing.assert_array_equal(den.gt.ids, plain.gt.ids)
    np.testing.assert_array_equal(den.gt.depth_z, plain.gt.depth_z)
    # The raw beauty is the same path tracing, with the guides rendered beside it.
    np.testing.assert_allclose(den.raw, plain.beauty, atol=1e-5)
    assert not np.allclose(den.beauty, den.raw, atol=1e-3)


def test_the_exr_holds_the_denoised_beauty_and_the_raw_one_beside_it(walking_museum, tmp_path):
    from usdcrowd.cli import main
    from usdcrowd.render.final.exr import read_frame_exr

    out = tmp_path / "render"
    assert main(["render", str(walking_museum), "--frames", "3:4", "--resolution", "96x54", "--spp", "8", "-o",
                 str(out), "--no-progress"]) == 0
    header, ch = read_frame_exr(out / "exr" / "frame.0003.exr")
    for name in ("R", "G", "B", "raw.R", "raw.G", "raw.B", "id", "albedo.R"):
        assert name in ch, name
    assert not np.allclose(ch["R"], ch["raw.R"])
    off = tmp_path / "plain"
    assert main(["render", str(walking_museum), "--frames", "3:4", "--resolution", "96x54", "--spp", "8", "-o",
                 str(off), "--no-progress", "--no-denoise"]) == 0
    _, plain = read_frame_exr(off / "exr" / "frame.0003.exr")
    assert "raw.R" not in plain
    np.testing.assert_array_equal(plain["id"], ch["id"])
    np.testing.assert_allclose(plain["R"], ch["raw.R"], atol=1e-5)


def test_sample_passes_are_powers_of_two_and_squares_where_the_sampler_needs_them():
    for spp in range(1, 300):
        for sampler, ok in (("independent", lambda n: n & (n - 1) == 0),
                            ("multijitter", lambda n: n & (n - 1) == 0 and int(np.sqrt(n)) ** 2 == n)):
            parts = sample_passes(spp, sampler)
            assert sum(parts) == spp and all(ok(n) for n in parts), (spp, sampler, parts)


def test_a_missing_denoiser_is_one_clear_line(monkeypatch):
    import sys

    from usdcrowd.core.errors import UsdcrowdError
    from usdcrowd.render.final.frame import require_denoiser

    monkeypatch.setitem(sys.modules, "pyoidn", None)
    with pytest.raises(UsdcrowdError, match="pip install 'usdcrowd\\[final\\]'"):
        require_denoiser()


def test_a_pinhole_frames_guides_are_trusted_as_clean(walking_museum, reference, monkeypatch):
    """A pinhole's averaged first hits are noise-free guides: told so (no prefilter), OIDN comes closer.

    Through a lens (defocus) or a shutter (sharp guides, blurred beauty) they are not, and OIDN prefilters.
    """
    import usdcrowd.render.final.frame as frame

    oidn, calls = frame.denoise, []

    def spy(color, albedo, normal, clean_aux=False):
        calls.append((color, albedo, normal, clean_aux))
        return oidn(color, albedo, normal, clean_aux)

    monkeypatch.setattr(frame, "denoise", spy)
    for seed in (1, 2, 3):
        FrameRenderer(walking_museum, None, (W, H), spp=16, max_depth=4, ground_truth=False, denoise=True,
                      seed=seed).render(FRAME)
    FrameRenderer(walking_museum, None, (W, H), spp=4, max_depth=2, ground_truth=False, denoise=True,
                  shutter=0.5, subframes=2).render(FRAME)
    assert [c[3] for c in calls] == [True, True, True, False]
    err = {clean: np.mean([relative_mse(oidn(*c[:3], clean_aux=clean), reference) for c in calls[:3]])
           for clean in (True, False)}
    assert err[True] < err[False], err
