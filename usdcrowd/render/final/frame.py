"""One frame: update what moved, render the beauty, cast the ground-truth rays.

Beauty is the scene's path tracer through the sensor (stratified sub-pixel
positions, box reconstruction filter, ``spp`` samples), plus ``people_spp``
more samples on the pixels that see a person (:mod:`.pixel_samples`).

Ground truth is *not* filtered: one ray per pixel, through the pixel centre
(a 1-sample box-filtered pass), cast with ``scene.ray_intersect``. At the
first hit we read the distance, position, shading normal, diffuse albedo
and the ``face_gtid`` attribute (:mod:`.meshes`), so every channel of a
pixel describes the same surface point and ids are exact integers that do
not depend on the order of ``scene.shapes()``.

The "alone" coverage of each agent (the pixels it would cover if nothing
hid it, used for the visibility fraction) comes from peeling: the rays of
pixels inside any agent's projected box are continued through every surface
until they leave the scene, and each agent hit on the way is counted.
Same rays, same pixel centres, so visible pixels are a subset of alone
pixels exactly.
"""

from __future__ import annotations

import os
import time as _time
from dataclasses import dataclass, field

import numpy as np

from ...character.poses import AgentPoses
from ...core.shading import SCENERY_ID_BASE, is_agent_id
from ...core.view import CameraView
from ...scenario.shot_scene import ShotScene
from ..settings import RenderSettings
from . import variant as _variant
from .build import AGENTS_KEY, SENSOR_KEY, BuiltScene, agent_vertices, build_scene, posed_scenery
from .camera import pixel_rays, sensor_to_world
from .pixel_samples import merge_samples, sample_pixels

SAMPLER = "multijitter"             # the least noise per second on the demo's frames (tools/bench.py render)
GUIDE_AOVS = "albedo:albedo,nn:sh_normal"
GUIDE_SPP = 16                      # more guide samples cost time and did not help OIDN (tools/bench.py render)
SQUARE_SAMPLERS = ("stratified", "multijitter")
from .meshes import GTID_ATTRIBUTE, decode_ids, float_buffer

# Seeds of a frame's sample sets, as offsets from the frame's seed (primes, so the sets never share a seed):
GUIDE_SEED = 104729                 # the denoiser's guides
PEOPLE_SEED = 32452843              # the people's samples (render.final.pixel_samples)
SUBFRAME_SEED = 15485863            # times the sub-frame's number (1, 2, ...) under an open shutter
PASS_SEED = 7919                    # times the pass's number, for a sample count taken in passes

# Peeling stops after this many surfaces along a ray (a body is two).
MAX_PEEL_LAYERS = 64
# People's extra samples also go to pixels this close to one whose centre sees a person (partly covered).
PEOPLE_MARGIN = 1


@dataclass
class GroundTruth:
    """Per-pixel ground truth of one frame, sampled at pixel centres.

    Attributes
    ----------
    ids : (h, w) uint32
        Agent track id, scenery id (>= SCENERY_ID_BASE), light shape id (>= LIGHT_ID_BASE) or 0 (background).
    depth_z : (h, w) float32
        Distance along the camera's view axis, metres; +inf where nothing is hit.
    depth_distance : (h, w) float32
        Euclidean distance to the camera centre, metres; +inf where nothing is hit.
    position : (h, w, 3) float32
        World position (canonical Z-up metres); 0 where nothing is hit.
    normal : (h, w, 3) float32
        World shading normal turned toward the camera; 0 where nothing is hit.
    albedo : (h, w, 3) float32
        Diffuse reflectance, linear RGB; 0 where nothing is hit.
    alone_pixels : dict[int, int]
        Agent track id -> pixels it covers with every other surface removed.
    """

    ids: np.ndarray
    depth_z: np.ndarray
    depth_distance: np.ndarray
    position: np.ndarray
    normal: np.ndarray
    albedo: np.ndarray
    alone_pixels: dict[int, int] = field(default_factory=dict)


@dataclass
class FrameResult:
    """Everything rendered for one time code.

    Attributes
    ----------
    time : float
    beauty : (h, w, 3) float32
        Linear RGB (Rec.709 primaries), scene-referred.
    gt : GroundTruth or None
    camera : CameraView
    poses : AgentPoses
    vertices : (n, v, 3) float32
        Skinned body vertices of every agent (hidden ones included).
    id_paths : dict[int, str]
        Ground-truth id -> prim path.
    seconds : dict[str, float]
        Wall time of "update", "beauty", "denoise" and "ground_truth".
    raw : (h, w, 3) float32 or None
        The beauty as path traced, when ``beauty`` is its denoised version.
    """

    time: float
    beauty: np.ndarray
    gt: GroundTruth | None
    camera: CameraView
    poses: AgentPoses
    vertices: np.ndarray
    id_paths: dict[int, str]
    seconds: dict[str, float]
    raw: np.ndarray | None = None       # (h, w, 3) float32 beauty before denoising (None when not denoised)


def sample_passes(spp: int, sampler: str) -> list[int]:
    """The sample counts of the passes that make ``spp`` (see :meth:`FrameRenderer._film`)."""
    base = 4 if sampler in SQUARE_SAMPLERS else 2
    parts, k = [], 0
    while base ** (k + 1) <= spp:
        k += 1
    left = int(spp)
    for e in range(k, -1, -1):
        while left >= base ** e:
            parts.append(base ** e)
            left -= base ** e
    return parts


def people_pixels(ids: np.ndarray, margin: int = PEOPLE_MARGIN) -> np.ndarray:
    """(k,) int64 flat indices of the pixels that see a person, and of those within ``margin`` pixels.

    ``ids`` is an (h, w) id pass at pixel centres; a person's edge pixel
    whose centre misses the body is caught by the margin (4-neighbours,
    ``margin`` times).
    """
    from scipy.ndimage import binary_dilation

    people = is_agent_id(ids)
    if margin > 0 and people.any():
        people = binary_dilation(people, iterations=int(margin))
    return np.flatnonzero(people.ravel())


def require_denoiser():
    """Intel Open Image Denoise's Python binding, or a one-line error saying how to install it."""
    from ...core.errors import UsdcrowdError

    try:
        import pyoidn
    except ImportError:
        raise UsdcrowdError("denoising needs Intel Open Image Denoise: pip install 'usdcrowd[final]' (pyoidn), "
                            "or render with --no-denoise") from None
    return pyoidn


def denoise(color: np.ndarray, albedo: np.ndarray, normal: np.ndarray, clean_aux: bool = False) -> np.ndarray:
    """(h, w, 3) float32 beauty denoised by OIDN's RT filter (HDR), guided by albedo and normal.

    ``clean_aux`` tells OIDN the guides are noise-free, so it does not
    prefilter them: true of a pinhole camera's first hits averaged over a
    pixel (they vary only at edges, which the average resolves); not through
    a defocused lens, nor when the guides are sharp and the beauty is
    motion-blurred. On the bench's museum frame it gives 8 % less error at 32
    and 64 spp.
    """
    pyoidn = require_denoiser()
    out = pyoidn.denoise(np.ascontiguousarray(color, np.float32),
                         np.ascontiguousarray(np.clip(albedo, 0, 1), np.float32),
                         np.ascontiguousarray(np.clip(normal, -1, 1), np.float32), hdr=True, clean_aux=bool(clean_aux))
    return np.asarray(out, dtype=np.float32)


class FrameRenderer:
    """Renders frames of one shot through one camera; the Mitsuba scene is built once.

    Parameters
    ----------
    shot : ShotScene or path-like
    camera : str, optional
        Camera prim path (default: the first camera).
    resolution : (int, int)
        Width, height in pixels.
    spp : int
        Beauty samples per pixel.
    max_depth : int
        Longest light path.
    variant : str, optional
        Mitsuba variant, or None/"auto" for :func:`variant.choose_variant`.
    ground_truth : bool
        Also compute the per-pixel ground truth.
    seed : int
        Base seed of the beauty sampler; frame ``t`` uses ``seed + round(t * 1000)``.
    threads : int, optional
        Dr.Jit worker threads (LLVM), e.g. cores / workers.
    sampler : str
        Mitsuba sampler of the beauty (default multijitter: the least noise
        per second measured on the demo's frames).
    shutter : float
        Motion blur: how long the shutter is open, in frames (0.5 is a
        180-degree shutter; 0, the default, none). See :meth:`_motion_blurred`.
    subframes : int
        Times the shutter interval is sampled at (each with spp / subframes
        samples).
    people_spp : int
        More samples on each pixel that sees a person (and its neighbours),
        where the denoiser cannot help (:mod:`.pixel_samples`); 0: none. On
        JIT variants (the scalar fallback ignores it).
    denoise : bool
        Denoise the beauty with Intel Open Image Denoise, guided by albedo
        and shading normal averaged over up to GUIDE_SPP samples per pixel
        through the same box-filtered film; the path-traced beauty is kept
        as ``FrameResult.raw``.
    """

    @classmethod
    def from_settings(cls, shot, camera: str | None, settings: RenderSettings, threads: int | None = None):
        """The renderer of ``settings`` (checked where they were made) through ``camera``."""
        return cls(shot, camera, settings.resolution, settings.spp, settings.max_depth, settings.variant,
                   settings.ground_truth, settings.seed, threads, sampler=settings.sampler, denoise=settings.denoise,
                   shutter=settings.shutter, subframes=settings.subframes, people_spp=settings.people_spp)

    def __init__(self, shot, camera: str | None = None, resolution=(640, 360), spp: int = 64,
                 max_depth: int = 6, variant: str | None = None, ground_truth: bool = True, seed: int = 0,
                 threads: int | None = None, sampler: str = SAMPLER, denoise: bool = False,
                 shutter: float = 0.0, subframes: int = 8, people_spp: int = 0):
        # The one place settings are checked (RenderSettings), whoever calls.
        checked = RenderSettings(resolution=resolution, spp=spp, max_depth=max_depth, seed=seed, sampler=sampler,
                                 denoise=denoise, shutter=shutter, subframes=subframes, people_spp=people_spp)
        self.shot = shot if isinstance(shot, ShotScene) else ShotScene(os.fspath(shot))
        self.variant = _variant.choose_variant(variant)
        mi = _variant.activate(self.variant)
        if threads and self.variant.startswith("llvm"):
            import drjit as dr

            dr.set_thread_count(int(threads))
        self.camera_path = camera
        self.width, self.height = checked.resolution
        self.spp, self.max_depth, self.ground_truth, self.seed = int(spp), int(max_depth), ground_truth, int(seed)
        self.sampler, self.denoise = sampler, bool(denoise)
        self.shutter, self.subframes = float(shutter), int(subframes) if shutter > 0 else 1
        self.people_spp = int(people_spp) if _variant.is_jit(self.variant) else 0
        if self.denoise:
            require_denoiser()
        t0 = float(self.shot.time_codes[0]) if len(self.shot.time_codes) else 0.0
        cam = self.shot.camera(camera, t0)
        self.camera_path = cam.path
        start = _time.perf_counter()
        # The sensor's own count is a valid one for its sampler (each render passes its own count).
        self.built: BuiltScene = build_scene(self.shot, cam, self.width, self.height,
                                             sample_passes(self.spp, self.sampler)[0], self.max_depth, t0,
                                             sampler=self.sampler)
        # The denoiser's guides: albedo and shading normal, a pass of their own through the same film
        # (box filter), averaged over up to GUIDE_SPP samples per pixel.
        self._guides = mi.load_dict({"type": "aov", "aovs": GUIDE_AOVS}) if self.denoise else None
        self._thin_lens = cam.depth_of_field     # the lens type is the first frame's
        self.build_seconds = _time.perf_counter() - start
        self._mi = mi

    # ----------------------------------------------------------------- update
    def _update(self, t: float) -> tuple[CameraView, AgentPoses, np.ndarray]:
        mi = self._mi
        params = self.built.params
        cam = self.shot.camera(self.camera_path, t)
        poses = self.shot.agents(t)
        vertices = self.shot.skinned_vertices(poses) if len(poses) else np.zeros((0, 0, 3), np.float32)
        if len(poses):
            params[f"{AGENTS_KEY}.vertex_positions"] = float_buffer(agent_vertices(self.shot, poses, vertices))
        for a in self.built.animated:
            verts, _ = posed_scenery(a.item, t)
            params[f"{a.key}.vertex_positions"] = float_buffer(verts)
        params[f"{SENSOR_KEY}.to_world"] = mi.ScalarTransform4f(sensor_to_world(cam).tolist())
        params[f"{SENSOR_KEY}.x_fov"] = cam.fov_x()
        if self._thin_lens:                      # focus pulls and iris changes, frame by frame
            params[f"{SENSOR_KEY}.aperture_radius"] = cam.aperture_radius
            params[f"{SENSOR_KEY}.focus_distance"] = cam.focus_distance if cam.depth_of_field else 1e9
        with _variant.single_threaded_build():      # the same BVH, so the same bytes
            params.update()
        return cam, poses, vertices

    # ----------------------------------------------------------------- render
    def render(self, t: float) -> FrameResult:
        """Render time code ``t``: beauty, and ground truth if enabled."""
        mi = _variant.activate(self.variant)        # another renderer in this process may have switched it
        s0 = _time.perf_counter()
        cam, poses, vertices = self._update(float(t))
        s1 = _time.perf_counter()
        seed = self.seed + int(round(float(t) * 1000))
        gt = None
        if self.subframes > 1:
            s_gt = s1
            raw = self._motion_blurred(mi, float(t), seed)
            cam, poses, vertices = self._update(float(t))   # the ground truth and guides: at the frame's time
        else:
            if self.ground_truth:       # first: its pixel-centre ids also pick the people's pixels
                gt = self.cast_ground_truth(cam, vertices, poses)
            s_gt = _time.perf_counter()
            raw = self._beauty(mi, seed, self.spp, self.people_spp, cam, None if gt is None else gt.ids)
        s2 = _time.perf_counter()
        if self.denoise:
            guides = self._film(mi, seed + GUIDE_SEED, min(self.spp, GUIDE_SPP), self._guides)
            # Guides from a pinhole at the frame's time are clean; through a lens or a shutter they are not.
            clean = not self._thin_lens and self.subframes == 1
            beauty = denoise(raw, guides[..., 0:3], guides[..., 3:6], clean_aux=clean)
        else:
            beauty = raw
        s3 = _time.perf_counter()
        if self.ground_truth and gt is None:
            gt = self.cast_ground_truth(cam, vertices, poses)
        s4 = _time.perf_counter()
        return FrameResult(float(t), beauty, gt, cam, poses, vertices, dict(self.built.id_paths),
                           {"update": s1 - s0, "beauty": s2 - s_gt, "denoise": s3 - s2,
                            "ground_truth": (s_gt - s1) + (s4 - s3)}, raw if self.denoise else None)

    def _motion_blurred(self, mi, t: float, seed: int) -> np.ndarray:
        """(h, w, 3) beauty averaged over the shutter: the scene posed at ``subframes`` times centred on ``t``.

        Mitsuba 3 has no motion blur of deforming meshes (skinned characters),
        so the shutter is sampled in time instead: at sub-frame ``i`` the
        crowd, the animated scenery and the camera are posed at
        ``t + shutter * ((i + 0.5) / subframes - 0.5)`` (frames) and rendered
        with an equal share of the samples.
        """
        n = self.subframes
        share = max(1, self.spp // n)
        people = max(1, self.people_spp // n) if self.people_spp else 0
        total = None
        for i in range(n):
            cam, _, _ = self._update(t + self.shutter * ((i + 0.5) / n - 0.5))
            img = self._beauty(mi, seed + SUBFRAME_SEED * (i + 1), share, people, cam).astype(np.float64)
            total = img if total is None else total + img
        return (total / n).astype(np.float32)

    def _beauty(self, mi, seed: int, spp: int, people_spp: int, cam: CameraView,
                ids: np.ndarray | None = None) -> np.ndarray:
        """(h, w, 3) float32 path-traced beauty of the scene as posed: ``spp`` samples a pixel, and
        ``people_spp`` more where ``cam``'s pixel centres (and their margin) see a person.

        ``ids`` is the (h, w) id pass at those centres where the caller has it (else cast here).
        """
        img = self._film(mi, seed, spp)[..., :3]
        if people_spp <= 0:
            return img
        if ids is None:
            origin, direction, length, _, _ = pixel_rays(cam, self.width, self.height)
            ids = self._cast(origin, direction, length, full=False)["ids"].reshape(self.height, self.width)
        pixels = people_pixels(ids)
        extra, n = sample_pixels(self.built.scene, pixels, people_spp, seed + PEOPLE_SEED)
        return merge_samples(img, spp, pixels, extra, n)

    def _film(self, mi, seed: int, spp: int, integrator=None) -> np.ndarray:
        """(h, w, c) float32 film of the scene's path tracer (or of ``integrator``), the same bytes run after run.

        With the box filter each pixel's samples are consecutive lanes, summed
        by one thread as long as they do not straddle two of the JIT's blocks
        of lanes (a power of two): so the samples are taken in passes of
        powers of two (48 spp: 32 then 16), each deterministic, added up here
        in a fixed order. Stratified samplers need square counts: their passes
        are powers of four (48 spp: 16, 16, 16).
        """
        parts = sample_passes(spp, self.sampler)
        kw = {"integrator": integrator} if integrator is not None else {}
        if len(parts) == 1:
            return np.array(mi.render(self.built.scene, spp=spp, seed=seed, **kw), dtype=np.float32)
        total = None
        for k, n in enumerate(parts):
            img = np.array(mi.render(self.built.scene, spp=n, seed=seed + PASS_SEED * k, **kw), dtype=np.float64) * n
            total = img if total is None else total + img
        return (total / spp).astype(np.float32)

    # ----------------------------------------------------------- ground truth
    def cast_ground_truth(self, cam: CameraView, vertices: np.ndarray, poses: AgentPoses) -> GroundTruth:
        """Per-pixel ground truth at pixel centres (see the module's notes)."""
        w, h = self.width, self.height
        origin, direction, length, start, cos_axis = pixel_rays(cam, w, h)
        hit = self._cast(origin, direction, length, full=True)
        valid = hit["valid"]
        distance = np.where(valid, start + hit["t"], np.inf)
        normal = hit["normal"]
        facing = np.einsum("ij,ij->i", normal, direction) > 0
        normal[facing] *= -1.0
        zero3 = ~valid[:, None]
        gt = GroundTruth(
            ids=np.where(valid, hit["ids"], 0).astype(np.uint32).reshape(h, w),
            depth_z=(distance * cos_axis).astype(np.float32).reshape(h, w),
            depth_distance=distance.astype(np.float32).reshape(h, w),
            position=np.where(zero3, 0.0, hit["position"]).astype(np.float32).reshape(h, w, 3),
            normal=np.where(zero3, 0.0, normal).astype(np.float32).reshape(h, w, 3),
            albedo=np.where(zero3, 0.0, hit["albedo"]).astype(np.float32).reshape(h, w, 3))
        gt.alone_pixels = self._alone_pixels(cam, vertices, poses, origin, direction, length, hit)
        return gt

    def _alone_pixels(self, cam, vertices, poses, origin, direction, length, first_hit=None) -> dict[int, int]:
        """Agent id -> pixel centres its body covers, found by peeling through every surface.

        ``first_hit`` (the full-image cast of these rays, if already made)
        stands in for the first layer.
        """
        w, h = self.width, self.height
        if len(poses) == 0:
            return {}
        region = np.zeros((h, w), dtype=bool)
        for i in np.flatnonzero(poses.visible):
            uv, z = cam.project(vertices[i], w, h)
            front = z > cam.near
            if not front.any():
                continue
            if not front.all():
                # Part of the body is behind the camera: its projection is unbounded.
                region[:] = True
                break
            x0, y0 = np.floor(uv.min(0) - 0.5).astype(int)
            x1, y1 = np.ceil(uv.max(0) + 0.5).astype(int)
            region[max(y0, 0):min(y1, h), max(x0, 0):min(x1, w)] = True
        pixels = np.flatnonzero(region.ravel())
        o, d, remaining = origin[pixels], direction[pixels], length[pixels].copy()
        found_pixels, found_ids = [], []
        for layer in range(MAX_PEEL_LAYERS):
            if len(pixels) == 0:
                break
            if layer == 0 and first_hit is not None:
                hit = {k: first_hit[k][pixels] for k in ("valid", "t", "ids")}
            else:
                hit = self._cast(o, d, remaining, full=False)
            keep = hit["valid"]
            ids = hit["ids"]
            agent = keep & is_agent_id(ids)
            found_pixels.append(pixels[agent])
            found_ids.append(ids[agent])
            t = hit["t"][keep]
            p = o[keep] + d[keep] * t[:, None]
            eps = 1e-4 * np.maximum(1.0, np.abs(p).max(1))                  # step past the surface just hit
            pixels, d = pixels[keep], d[keep]
            o = p + d * eps[:, None]
            remaining = remaining[keep] - t - eps
            ok = remaining > 0
            pixels, o, d, remaining = pixels[ok], o[ok], d[ok], remaining[ok]
        if not found_ids:
            return {}
        key = np.unique(np.concatenate(found_pixels).astype(np.int64) * SCENERY_ID_BASE
                        + np.concatenate(found_ids).astype(np.int64))
        ids, counts = np.unique(key % SCENERY_ID_BASE, return_counts=True)
        return {int(i): int(c) for i, c in zip(ids, counts)}

    def _cast(self, origin: np.ndarray, direction: np.ndarray, maxt: np.ndarray, full: bool) -> dict:
        """Intersect rays with the scene.

        Parameters
        ----------
        origin, direction : (r, 3) float
        maxt : (r,) float
        full : bool
            Also read position, normal and albedo (else only t, valid, ids).

        Returns
        -------
        dict of numpy arrays
            ``valid`` (r,) bool, ``t`` (r,), ``ids`` (r,) uint32 and, if
            ``full``, ``position``, ``normal``, ``albedo`` (r, 3).
        """
        if not _variant.is_jit(self.variant):
            return self._cast_scalar(origin, direction, maxt, full)
        mi = self._mi
        import drjit as dr

        if len(origin) == 0:
            z = np.zeros((0, 3))
            return {"valid": np.zeros(0, bool), "t": np.zeros(0), "ids": np.zeros(0, np.uint32),
                    "position": z, "normal": z, "albedo": z}
        o = origin.astype(np.float32).T
        d = direction.astype(np.float32).T
        ray = mi.Ray3f(mi.Point3f(*[mi.Float(c) for c in o]), mi.Vector3f(*[mi.Float(c) for c in d]))
        ray.maxt = mi.Float(maxt.astype(np.float32))
        si = self.built.scene.ray_intersect(ray)
        valid = si.is_valid()
        halves = si.shape.eval_attribute_3(GTID_ATTRIBUTE, si, valid)
        out = {"valid": si.is_valid(), "t": si.t, "halves": halves}
        if full:
            out.update(position=si.p, normal=si.sh_frame.n,
                       albedo=si.bsdf().eval_diffuse_reflectance(si, valid))
        dr.eval(*out.values())
        res = {"valid": np.array(out["valid"], dtype=bool), "t": np.array(out["t"], dtype=np.float64)}
        res["ids"] = np.where(res["valid"], decode_ids(np.array(out["halves"]).reshape(3, -1).T), 0).astype(np.uint32)
        if full:
            for k in ("position", "normal", "albedo"):
                res[k] = np.array(out[k], dtype=np.float64).reshape(3, -1).T
        return res

    def _cast_scalar(self, origin, direction, maxt, full) -> dict:
        """The same as :meth:`_cast`, one ray at a time (scalar_rgb fallback; slow but exact)."""
        mi = self._mi
        r = len(origin)
        res = {"valid": np.zeros(r, bool), "t": np.full(r, np.inf), "ids": np.zeros(r, np.uint32),
               "position": np.zeros((r, 3)), "normal": np.zeros((r, 3)), "albedo": np.zeros((r, 3))}
        scene = self.built.scene
        for k in range(r):
            ray = mi.Ray3f(mi.Point3f(*origin[k]), mi.Vector3f(*direction[k]))
            ray.maxt = float(maxt[k])
            si = scene.ray_intersect(ray)
            if not si.is_valid():
                continue
            res["valid"][k] = True
            res["t"][k] = si.t
            res["ids"][k] = decode_ids(np.array(si.shape.eval_attribute_3(GTID_ATTRIBUTE, si)))
            if full:
                res["position"][k] = np.array(si.p)
                res["normal"][k] = np.array(si.sh_frame.n)
                res["albedo"][k] = np.array(si.bsdf().eval_diffuse_reflectance(si))
        return res
