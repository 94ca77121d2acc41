"""More samples on the people (issue 14, point 2): where the denoiser leaves noise, samples take it out."""

from __future__ import annotations

import json

import numpy as np
import pytest

from usdcrowd.render.final.frame import FrameRenderer, people_pixels
from usdcrowd.render.final.pixel_samples import merge_samples, padded_count, sample_pixels
from usdcrowd.core.shading import LIGHT_ID_BASE, SCENERY_ID_BASE

W, H = 128, 72
FRAME = 6


def relative_mse(x: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Per-pixel (x - ref)^2 / (ref^2 + 0.01), averaged over channels: the render benchmark's measure."""
    return np.mean((x - ref) ** 2 / (ref ** 2 + 1e-2), axis=-1)


@pytest.fixture(scope="module")
def museum_reference(walking_museum):
    """The walking museum's frame at 1,024 spp (independent sampler, a seed of its own) and its id pass."""
    pytest.importorskip("mitsuba")
    r = FrameRenderer(walking_museum, None, (W, H), spp=1024, max_depth=4, sampler="independent",
                      seed=12345).render(FRAME)
    return r.beauty, r.gt.ids


def test_the_people_pixels_are_the_agents_and_a_margin_around_them():
    ids = np.full((8, 10), SCENERY_ID_BASE + 3, np.uint32)
    ids[0, :] = 0                                    # background
    ids[3:5, 4:6] = 7                                # a person
    ids[6, 0] = LIGHT_ID_BASE + 1                    # a light's shape: not a person
    exact = np.zeros(ids.shape, bool)
    exact[3:5, 4:6] = True
    np.testing.assert_array_equal(people_pixels(ids, margin=0), np.flatnonzero(exact))
    # The margin: the 4-neighbours of the person's pixels (partly covered pixels whose centre missed).
    edge = exact.copy()
    edge[2, 4:6] = edge[5, 4:6] = edge[3:5, 3] = edge[3:5, 6] = True
    np.testing.assert_array_equal(people_pixels(ids, margin=1), np.flatnonzero(edge))
    assert len(people_pixels(np.zeros((4, 4), np.uint32))) == 0


def test_padded_pixel_counts_hold_the_pixels_and_take_few_sizes():
    k = np.arange(1, 640 * 360 + 1)
    padded = np.array([padded_count(int(n)) for n in k])
    assert (padded >= k).all() and (padded <= np.ceil(k * 2 ** 0.25)).all()
    assert (np.diff(padded) >= 0).all()
    assert len(np.unique(padded)) < 80           # each size compiles a kernel once


@pytest.fixture(params=["one launch", "in chunks"])
def lane_limit(request, monkeypatch):
    """Pixels traced in one kernel launch, or in chunks of 100 pixels (as a 1080p close-up would be)."""
    import usdcrowd.render.final.pixel_samples as pixel_samples

    if request.param == "in chunks":
        monkeypatch.setattr(pixel_samples, "MAX_LANES", 100 * 256)
    return request.param


def test_samples_at_chosen_pixels_converge_as_the_films(walking_museum, museum_reference, lane_limit):
    """The same estimate as Mitsuba's film: as close to the converged frame as the film's own samples.

    A pixel's samples falling in another pixel or a wrong average would leave a bias that 256 samples
    do not hide (a missing aperture sample: the thin-lens test below).
    """
    reference, _ = museum_reference
    r = FrameRenderer(walking_museum, None, (W, H), spp=256, max_depth=4, ground_truth=False, seed=3)
    film = r.render(FRAME).beauty
    ours, n = sample_pixels(r.built.scene, np.arange(W * H), 256, seed=4)
    assert n == 256
    ours = ours.reshape(H, W, 3)
    e_film, e_ours = relative_mse(film, reference).mean(), relative_mse(ours, reference).mean()
    assert e_ours < 1.3 * e_film, (e_ours, e_film)
    np.testing.assert_allclose(ours.mean((0, 1)), reference.mean((0, 1)), rtol=0.01)
    # The same bytes run after run (each pixel summed in one order).
    again, _ = sample_pixels(r.built.scene, np.arange(W * H), 256, seed=4)
    np.testing.assert_array_equal(again.reshape(H, W, 3), ours)


def test_through_a_thin_lens_they_blur_as_the_films(tmp_path):
    """The aperture is drawn where Mitsuba's film draws it: a defocused edge spreads as much."""
    from tests.helpers.render import dof_box_stage, edge_width

    path = dof_box_stage(tmp_path, f_stop=1.0, focus=3.0)
    w, h = 128, 96
    r = FrameRenderer(path, "/World/Cam", (w, h), spp=256, max_depth=2, ground_truth=False)
    film = r.render(1).beauty
    ours, _ = sample_pixels(r.built.scene, np.arange(w * h), 256, seed=5)
    blur_film, blur_ours = edge_width(film), edge_width(ours.reshape(h, w, 3))
    assert blur_film > 2 and blur_ours == pytest.approx(blur_film, rel=0.1), (blur_ours, blur_film)


def test_a_sampler_that_rounds_the_count_says_how_many_it_took(walking_museum):
    r = FrameRenderer(walking_museum, None, (W, H), spp=4, max_depth=2, ground_truth=False)
    rgb, n = sample_pixels(r.built.scene, np.array([5, 700, W * H - 1]), 32, seed=1)    # multijitter: 5 x 7
    assert n == 35 and rgb.shape == (3, 3) and np.isfinite(rgb).all()
    with pytest.raises(ValueError, match="pixel indices"):
        sample_pixels(r.built.scene, np.array([W * H]), 4, seed=1)


def test_merging_weighs_each_sample_once():
    beauty = np.ones((2, 3, 3), np.float32)
    out = merge_samples(beauty, 16, np.array([4]), np.full((1, 3), 4.0, np.float32), 48)
    assert out[1, 1].tolist() == [3.25] * 3                  # (16 * 1 + 48 * 4) / 64
    assert (np.delete(out.reshape(-1, 3), 4, axis=0) == 1).all() and (beauty == 1).all()


def test_people_samples_clean_the_people_and_leave_the_rest_alone(walking_museum, museum_reference):
    reference, ids = museum_reference
    people = np.zeros(H * W, bool)
    people[people_pixels(ids)] = True
    people = people.reshape(H, W)
    assert 50 < people.sum() < 0.5 * people.size
    plain = FrameRenderer(walking_museum, None, (W, H), spp=16, max_depth=4, ground_truth=False,
                          seed=1).render(FRAME).beauty
    more = FrameRenderer(walking_museum, None, (W, H), spp=16, max_depth=4, ground_truth=False, seed=1,
                         people_spp=64)
    a, b = more.render(FRAME).beauty, more.render(FRAME).beauty
    np.testing.assert_array_equal(a, b)                               # the same bytes run after run
    # With ground truth on, its id pass picks the pixels: the same ones, so the same bytes.
    with_gt = FrameRenderer(walking_museum, None, (W, H), spp=16, max_depth=4, seed=1, people_spp=64).render(FRAME)
    np.testing.assert_array_equal(with_gt.beauty, a)
    np.testing.assert_array_equal(a[~people], plain[~people])         # the rest: the same samples
    # 16 + 64 samples: a fifth of the variance expected; at least 2.5 times less error asked.
    e_plain, e_more = relative_mse(plain, reference)[people].mean(), relative_mse(a, reference)[people].mean()
    assert e_more * 2.5 < e_plain, (e_more, e_plain)
    # Unbiased: the people's level is the converged frame's.
    np.testing.assert_allclose(a[people].mean(0), reference[people].mean(0), rtol=0.02)


def test_people_samples_reach_the_manifest_from_the_command_line(walking_museum, tmp_path, capsys):
    from usdcrowd.cli import main

    out = tmp_path / "render"
    assert main(["render", str(walking_museum), "--frames", "3:3", "--resolution", "64x36", "--spp", "4",
                 "--people-spp", "9", "--no-ground-truth", "-o", str(out), "--no-progress"]) == 0
    from usdcrowd.render.final.variant import choose_variant, is_jit

    taken = 9 if is_jit(choose_variant()) else 0            # the scalar fallback takes none
    assert json.loads((out / "manifest.json").read_text())["header"]["settings"]["people_spp"] == taken
    assert main(["render", str(walking_museum), "--people-spp", "-1", "-o", str(tmp_path / "x")]) == 2
    assert "--people-spp" in capsys.readouterr().err


def test_the_scalar_fallback_records_no_people_samples(walking_museum, tmp_path):
    """The scalar variant takes no people's samples: its manifest says 0, the JIT one what was asked."""
    from usdcrowd.render.sequence import render_sequence, resolve_variant
    from usdcrowd.render.settings import settings_from_preset

    assert resolve_variant(settings_from_preset("groundtruth", people_spp=9, variant="llvm_ad_rgb")).people_spp == 9
    settings = settings_from_preset("groundtruth", resolution=(8, 6), spp=1, people_spp=9, ground_truth=False,
                                    denoise=False, variant="scalar_rgb")
    render_sequence(walking_museum, tmp_path / "r", frames=[FRAME], settings=settings, executor="inline",
                    progress=False, sequence_files=False)
    header = json.loads((tmp_path / "r" / "manifest.json").read_text())["header"]
    assert header["settings"]["people_spp"] == 0


def test_people_samples_follow_the_crowd_through_an_open_shutter(walking_museum, museum_reference):
    """With motion blur each sub-frame adds its share where the people are at that time."""
    reference, ids = museum_reference
    people = np.zeros(H * W, bool)
    people[people_pixels(ids)] = True
    from usdcrowd.render.final.camera import pixel_rays

    kw = dict(spp=8, max_depth=4, ground_truth=False, seed=2, shutter=0.5, subframes=2)
    plain = FrameRenderer(walking_museum, None, (W, H), **kw).render(FRAME).beauty
    renderer = FrameRenderer(walking_museum, None, (W, H), people_spp=32, **kw)
    more = renderer.render(FRAME).beauty
    # The people's pixels at each sub-frame's time (a quarter frame either side): only those change.
    seen = np.zeros(H * W, bool)
    for t in (FRAME - 0.125, FRAME + 0.125):
        cam, _, _ = renderer._update(t)
        origin, direction, length, _, _ = pixel_rays(cam, W, H)
        seen[people_pixels(renderer._cast(origin, direction, length, full=False)["ids"].reshape(H, W))] = True
    changed = np.any(more != plain, axis=-1).ravel()
    assert changed[seen].mean() > 0.95 and not changed[~seen].any()
    assert np.isfinite(more).all()
    # Unbiased: the people's level is the converged frame's (at the frame's time; they move a little).
    np.testing.assert_allclose(more.reshape(-1, 3)[people].mean(0), reference.reshape(-1, 3)[people].mean(0),
                               rtol=0.03)
