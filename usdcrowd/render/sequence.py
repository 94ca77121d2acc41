"""Render a shot's frames to disk, resumable, locally or on a Ray cluster.

Layout of an output folder (one camera)::

    exr/frame.0001.exr     beauty + ground truth (see render.final.exr)
    png/frame.0001.png     display frame (sRGB, colour-science)
    json/frame.0001.json   annotations (groundtruth.annotate)
    manifest.json          settings + per frame: files with size and sha256
    mot/                   MOTChallenge: gt/gt.txt, seqinfo.ini, frames.csv, img1/
    coco.json              COCO instances + keypoints
    contact_sheet.png      frames with boxes and ids
    render.mp4             with --mp4 (needs imageio-ffmpeg)

Every file is written under a temporary name and renamed. A frame counts as
done when its files exist and match the manifest (size and sha256), or,
when the manifest missed it (killed between rename and manifest update),
when its EXR opens with the expected channels and its JSON parses. A re-run
renders only the frames that are not done, then rebuilds the sequence
files from every frame's JSON. Changing settings that alter pixels
(resolution, spp, camera...) invalidates every frame.

Executors: ``inline`` (this process), ``local`` (``workers`` processes,
spawn context; each builds the Mitsuba scene once and renders the frames
it is handed) and ``ray`` (one actor per worker on a Ray cluster, output
folder on a shared file system).
"""

from __future__ import annotations

import contextlib
import json
import os
import time as _time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..atomic import atomic_path, clean_partials, file_sha256, output_dir
from ..core.errors import UsdcrowdError
from .settings import RenderSettings, settings_from_preset

MANIFEST = "manifest.json"


def resolve_variant(settings: RenderSettings) -> RenderSettings:
    """Set ``settings.variant`` to the Mitsuba variant that will render, and drop what it cannot do.

    The scalar fallback takes no people's samples (they are JIT launches), so
    its ``people_spp`` is 0: the manifest records the samples the frames got.
    Returns ``settings`` (changed in place).
    """
    from .final import variant as _variant

    settings.variant = _variant.choose_variant(settings.variant)
    if not _variant.is_jit(settings.variant) and settings.people_spp > 0:
        settings.people_spp = 0
    return settings


# --------------------------------------------------------------- frame files
def frame_tag(t: float) -> str:
    """File tag of a time code: ``0001`` for whole frames, ``0001.500`` for sub-frames."""
    t = float(t)
    return f"{int(round(t)):04d}" if abs(t - round(t)) < 1e-6 else f"{t:08.3f}"


def frame_files(t: float, ground_truth: bool) -> dict[str, str]:
    """Kind -> path relative to the output folder of one frame's files."""
    tag = frame_tag(t)
    files = {"exr": f"exr/frame.{tag}.exr", "png": f"png/frame.{tag}.png"}
    if ground_truth:
        files["json"] = f"json/frame.{tag}.json"
    return files


def _file_record(out: Path, rel: str) -> dict:
    p = out / rel
    return {"size": p.stat().st_size, "sha256": file_sha256(p)}


def expected_channels(settings: RenderSettings) -> list[str]:
    from .final.exr import BEAUTY, GROUND_TRUTH, RAW_BEAUTY

    names = list(BEAUTY)
    if settings.denoise:
        names += list(RAW_BEAUTY)
    if settings.ground_truth:
        names += [c for c in GROUND_TRUTH if c.split(".")[0] in settings.aovs]
    return names


def render_frame_to_disk(renderer, metadata, t: float, out_dir, settings: RenderSettings) -> dict:
    """Render one frame and write its files (each atomically).

    Returns
    -------
    dict
        Manifest entry: time, files (relative path -> size, sha256), seconds.
    """
    from ..groundtruth import frame_json
    from ..groundtruth.annotate import annotate_frame
    from .colour import convert, write_png
    from .final.exr import channels_of, write_frame_exr

    out = Path(out_dir)
    files = frame_files(t, settings.ground_truth)
    result = renderer.render(t)
    w0 = _time.perf_counter()
    beauty = convert(result.beauty, "sRGB", settings.working_space)
    raw = convert(result.raw, "sRGB", settings.working_space) if result.raw is not None else None
    channels = channels_of(beauty, result.gt, raw)
    keep = set(expected_channels(settings))
    channels = {k: v for k, v in channels.items() if k in keep}
    write_png(beauty, out / files["png"], settings.working_space, settings.exposure)
    if settings.ground_truth:
        record = annotate_frame(result, metadata)
        record["files"] = {k: v for k, v in files.items() if k != "json"}
        frame_json.write(record, out / files["json"])
    # The EXR goes last, so a frame whose EXR is on disk has all its files.
    write_frame_exr(out / files["exr"], channels, result.id_paths,
                    {"usdcrowd:camera": result.camera.path, "usdcrowd:time": result.time,
                     "usdcrowd:workingSpace": settings.working_space,
                     SETTINGS_ATTRIBUTE: settings_json(settings),
                     "usdcrowd:depthConvention": "depth.z: along the view axis; depth.distance: to the camera "
                                                 "centre; metres; +inf where no surface"})
    seconds = dict(result.seconds, write=_time.perf_counter() - w0)
    return {"time": float(t), "files": {rel: _file_record(out, rel) for rel in files.values()}, "seconds": seconds}


# ------------------------------------------------------------------ manifest
class Manifest:
    """``manifest.json``: the settings and every finished frame's files, rewritten atomically."""

    def __init__(self, out_dir, header: dict):
        self.path = Path(out_dir) / MANIFEST
        self.header = header
        self.frames: dict[str, dict] = {}
        self._dirty, self._saved_at = False, float("-inf")
        if self.path.exists():
            try:
                old = json.loads(self.path.read_text())
            except (OSError, ValueError):
                old = {}
            if old.get("header") == header:
                self.frames = old.get("frames", {})

    def save(self) -> None:
        with atomic_path(self.path) as tmp:
            tmp.write_text(json.dumps({"header": self.header, "frames": self.frames}, indent=1, sort_keys=True))

    # Rewriting the whole manifest after every frame would make a long
    # sequence's writes grow with the square of its length: at most this often.
    SAVE_EVERY_S = 2.0

    def add(self, entry: dict) -> None:
        """Record a finished frame; saved now if the last save is SAVE_EVERY_S old (else by :meth:`flush`)."""
        import time

        self.frames[frame_tag(entry["time"])] = entry
        self._dirty = True
        if time.monotonic() - self._saved_at >= self.SAVE_EVERY_S:
            self.flush()

    def flush(self) -> None:
        """Save if frames were added since the last save (a frame not saved is rendered again on resume)."""
        import time

        if self._dirty:
            self.save()
            self._dirty = False
            self._saved_at = time.monotonic()


# The EXR header attribute naming the settings a frame was rendered with: a frame found on disk but not in
# the manifest is adopted only if they are the current ones.
SETTINGS_ATTRIBUTE = "usdcrowd:renderSettings"


def settings_json(settings: RenderSettings) -> str:
    """The settings that change a frame's pixels, as the JSON its EXR header holds."""
    return json.dumps(settings.fingerprint(), sort_keys=True)


def verify_frame(out_dir, t: float, manifest: Manifest, settings: RenderSettings) -> bool:
    """True if frame ``t``'s outputs exist and are whole (see the module's notes)."""
    from ..groundtruth import frame_json
    from .final.exr import channel_names, read_frame_exr

    out = Path(out_dir)
    files = frame_files(t, settings.ground_truth)
    if not all((out / rel).is_file() for rel in files.values()):
        return False
    entry = manifest.frames.get(frame_tag(t))
    if entry is not None:
        recorded = entry.get("files", {})
        return set(recorded) == set(files.values()) and all(
            (out / rel).stat().st_size == rec["size"] and file_sha256(out / rel) == rec["sha256"]
            for rel, rec in recorded.items())
    # Written but not recorded (killed before the manifest was saved): adopt it if it reads back.
    try:
        header, _ = read_frame_exr(out / files["exr"], header_only=True)
        if set(channel_names(header)) != set(expected_channels(settings)):
            return False
        if header.get(SETTINGS_ATTRIBUTE) != settings_json(settings):     # made under other settings
            return False
        if settings.ground_truth:
            frame_json.read(out / files["json"])
        from PIL import Image

        with Image.open(out / files["png"]) as im:
            im.verify()
    except Exception:
        return False
    manifest.add({"time": float(t), "files": {rel: _file_record(out, rel) for rel in files.values()},
                  "seconds": None, "adopted": True})
    return True


# ----------------------------------------------------------------- executors
_WORKER: dict = {}


def _worker_init(shot_path, camera, settings: RenderSettings, threads):
    """Runs once in each worker process: build the Mitsuba scene.

    A user's mistake found here (a damaged animation) is kept and raised by the
    first frame's task, so it reaches the user as itself: raised in a process
    pool's initializer it would only break the pool.
    """
    from ..core.errors import UsdcrowdError

    try:
        _build_worker(shot_path, camera, settings, threads)
    except UsdcrowdError as exc:
        _WORKER["error"] = exc


def _pool_worker_init(shot_path, camera, settings: RenderSettings, threads):
    """A pool worker's start: interrupts are the parent's to handle (it stops the pool), then the scene."""
    from ..interrupts import worker_ignores_interrupts

    worker_ignores_interrupts()
    _worker_init(shot_path, camera, settings, threads)


def frame_renderer(shot, camera: str | None, settings: RenderSettings, threads: int | None = None):
    """The :class:`~.final.frame.FrameRenderer` that renders ``settings``' frames of ``shot`` through ``camera``."""
    from .final.frame import FrameRenderer

    return FrameRenderer.from_settings(shot, camera, settings, threads)


def _build_worker(shot_path, camera, settings, threads):
    import usdcrowd  # noqa: F401  (registers the schemas)

    from ..groundtruth.annotate import AgentMetadata
    from ..scenario.shot_scene import ShotScene

    shot = ShotScene(shot_path)
    _WORKER["renderer"] = frame_renderer(shot, camera, settings, threads)
    _WORKER["metadata"] = AgentMetadata.from_shot(shot) if settings.ground_truth else None
    _WORKER["settings"] = settings


def _worker_render(t, out_dir):
    if "error" in _WORKER:
        raise _WORKER["error"]
    return render_frame_to_disk(_WORKER["renderer"], _WORKER["metadata"], t, out_dir, _WORKER["settings"])


def _run_inline(shot_path, camera, settings, todo, out_dir, on_done):
    _worker_init(shot_path, camera, settings, None)
    for t in todo:
        on_done(_worker_render(t, out_dir))


def _run_local(shot_path, camera, settings, todo, out_dir, on_done, workers):
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    threads = max(1, (os.cpu_count() or 1) // workers)
    from ..interrupts import children_deaf_to_ctrl_c, stop_pool

    ctx = multiprocessing.get_context("spawn")
    pool = ProcessPoolExecutor(workers, mp_context=ctx, initializer=_pool_worker_init,
                               initargs=(shot_path, camera, settings, threads))
    try:
        with children_deaf_to_ctrl_c():     # the workers start on the first submit
            pending = {pool.submit(_worker_render, float(t), os.fspath(out_dir)) for t in todo}
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for fut in done:
                on_done(fut.result())
    except BaseException:
        stop_pool(pool)             # Ctrl-C, kill or an error: the frames left are not rendered
        raise
    pool.shutdown()


def _run_ray(shot_path, camera, settings, todo, out_dir, on_done, workers, address):
    try:
        import ray
    except ImportError:
        raise UsdcrowdError("--executor ray needs Ray: pip install 'usdcrowd[distributed]'") from None
    started = False
    actors = []
    if not ray.is_initialized():
        import logging

        # Ray's own start-up notes would bury the progress bar and our one-line errors.
        quiet = {"log_to_driver": False, "logging_level": logging.ERROR}
        if address:
            from .. import guard

            # A cluster's workers do not inherit this process's environment: hand them the guard's session.
            ray.init(address=address, runtime_env=guard.ray_runtime_env(), **quiet)
        else:
            # "local": a Ray instance for this run, never a cluster the user did not name
            # (a running one, or RAY_ADDRESS, would otherwise be joined).
            ray.init(address="local", num_cpus=max(workers, 1), include_dashboard=False, **quiet)
        started = True
    try:
        actor_cls = ray.remote(num_cpus=1)(_RayRenderer)
        threads = max(1, (os.cpu_count() or 1) // workers) if not address else None
        actors += [actor_cls.remote(shot_path, camera, settings, threads) for _ in range(workers)]
        queue = [float(t) for t in todo]
        in_flight = {}
        for a in actors:
            if queue:
                in_flight[a.render.remote(queue.pop(0), os.fspath(out_dir))] = a
        while in_flight:
            (ref,), _ = ray.wait(list(in_flight), num_returns=1)
            actor = in_flight.pop(ref)
            on_done(_ray_result(ray, ref))
            if queue:
                in_flight[actor.render.remote(queue.pop(0), os.fspath(out_dir))] = actor
    finally:
        if started:
            ray.shutdown()          # this run's Ray instance: its actors go with it
        else:
            for a in actors:        # a cluster's: stop this run's actors, mid-frame or not
                with contextlib.suppress(Exception):
                    ray.kill(a)


def _ray_result(ray, ref):
    """``ray.get(ref)``; a user's mistake found on a worker is raised as itself (one line), not as Ray's report."""
    try:
        return ray.get(ref)
    except ray.exceptions.RayTaskError as exc:
        cause = getattr(exc, "cause", None)
        if isinstance(cause, (UsdcrowdError, OSError)):
            raise cause from None
        raise


class _RayRenderer:
    """A Ray actor holding one FrameRenderer (the scene is built once per actor)."""

    def __init__(self, shot_path, camera, settings: RenderSettings, threads):
        _worker_init(shot_path, camera, settings, threads)

    def render(self, t, out_dir):
        return _worker_render(t, out_dir)


# ------------------------------------------------------------------ sequence
@dataclass
class SequenceResult:
    """What :func:`render_sequence` did and where everything is."""

    out_dir: str
    camera: str
    variant: str
    times: list[float]
    rendered: list[float]
    skipped: list[float]
    seconds_per_frame: float | None
    outputs: dict[str, str] = field(default_factory=dict)


def render_sequence(shot_path, out_dir, camera: str | None = None, frames=None,
                    settings: RenderSettings | None = None, executor: str = "local", workers: int = 1,
                    address: str | None = None, progress: bool = True, mp4: bool = False,
                    sequence_files: bool = True) -> SequenceResult:
    """Render ``frames`` of a shot through ``camera`` into ``out_dir``, resuming what is done.

    Parameters
    ----------
    shot_path : path-like
    out_dir : path-like
    camera : str, optional
        Camera prim path (default: the stage's first camera).
    frames : (t,) float array, optional
        Time codes (default: the stage's range).
    settings : RenderSettings, optional
        Default: the ``groundtruth`` preset.
    executor : {"local", "inline", "ray"}
    workers : int
        Processes (local) or actors (ray).
    address : str, optional
        Ray cluster address (default: start a local instance).
    progress : bool
        Show a tqdm bar (frames done, rate).
    mp4 : bool
        Also encode the display frames as an MP4.
    sequence_files : bool
        Write MOT, COCO, the contact sheet (and MP4) after the frames.

    Returns
    -------
    SequenceResult
    """
    from tqdm import tqdm

    settings = replace(settings) if settings else settings_from_preset("groundtruth")    # the caller's, unchanged
    out = Path(out_dir)
    shot_path = os.fspath(Path(shot_path).resolve())
    shot, times, cam_path = _checked_request(shot_path, camera, frames, executor, address)
    resolve_variant(settings)
    output_dir(out, "render")
    header = {"shot": shot_path, "camera": cam_path, "settings": settings.fingerprint()}
    manifest = Manifest(out, header)
    done = [float(t) for t in times if verify_frame(out, t, manifest, settings)]
    finished = set(done)
    todo = [float(t) for t in times if float(t) not in finished]
    workers = max(0, min(workers, len(todo)))
    rendered: list[float] = []
    spent: list[float] = []
    bar = tqdm(total=len(times), initial=len(done), unit="frame", desc=f"render {Path(cam_path).name}",
               disable=not progress, dynamic_ncols=True)
    start = _time.perf_counter()

    def on_done(entry):
        manifest.add(entry)
        rendered.append(entry["time"])
        spent.append(sum(entry["seconds"].values()))
        bar.update(1)

    try:
        if todo:
            _run_frames(executor, shot_path, cam_path, settings, todo, out, on_done, workers, address)
    except BaseException:
        clean_partials(out)         # the frames in flight, abandoned (this run holds the folder)
        raise
    finally:
        manifest.flush()
        bar.close()
    wall = _time.perf_counter() - start
    result = SequenceResult(os.fspath(out), cam_path, settings.variant, [float(t) for t in times], sorted(rendered),
                            done, wall / len(rendered) if rendered else None)
    result.outputs["manifest"] = os.fspath(manifest.path)
    if sequence_files:
        result.outputs.update(write_sequence_files(out, times, settings, shot.fps, mp4=mp4))
    return result


def _checked_request(shot_path: str, camera: str | None, frames, executor: str, address: str | None):
    """(shot, (t,) float64 times, camera path), every mistake in the request refused before any work."""
    from ..scenario.shot_scene import ShotScene

    shot = ShotScene(shot_path)
    times = np.asarray(frames if frames is not None else shot.time_codes, dtype=np.float64)
    shot.check_times(times)
    if times.size == 0:
        raise UsdcrowdError("no frames to render")
    cam_path = shot.camera(camera, float(times[0])).path            # raises StageError on a bad camera
    # Lights and scenery are checked here too: an error raised while a worker
    # builds its scene would only say that the process pool broke.
    shot.lights, shot.scenery
    if executor not in ("local", "inline", "ray"):
        raise UsdcrowdError(f"unknown executor {executor!r} (local, inline, ray)")
    if address and executor != "ray":
        raise UsdcrowdError("--address is a Ray cluster's: give it with --executor ray", attribute="--address")
    return shot, times, cam_path


def _run_frames(executor: str, shot_path: str, cam_path: str, settings: RenderSettings, todo: list[float],
                out: Path, on_done, workers: int, address: str | None) -> None:
    """Render ``todo`` on the executor asked for (inline when a local run has no workers)."""
    if executor == "inline" or (executor == "local" and workers <= 0):
        _run_inline(shot_path, cam_path, settings, todo, out, on_done)
    elif executor == "local":
        _run_local(shot_path, cam_path, settings, todo, out, on_done, workers)
    else:
        _run_ray(shot_path, cam_path, settings, todo, out, on_done, max(workers, 1), address)


def write_sequence_files(out_dir, times, settings: RenderSettings, fps: float = 24.0, mp4: bool = False) -> dict:
    """MOT, COCO, contact sheet (and MP4) from the frames on disk; returns kind -> path."""
    from ..groundtruth import frame_json
    from ..groundtruth.contact_sheet import contact_sheet
    from ..groundtruth.coco import write_coco
    from ..groundtruth.mot import write_mot

    out = Path(out_dir)
    times = [float(t) for t in times]
    pngs = [os.fspath(out / frame_files(t, False)["png"]) for t in times]
    outputs = {}
    if settings.ground_truth:
        records = frame_json.Records([out / frame_files(t, True)["json"] for t in times])
    else:
        records = [{"time": t, "agents": []} for t in times]
    stride = float(np.median(np.diff(times))) if len(times) > 1 else 1.0
    if settings.ground_truth:
        outputs["mot"] = os.fspath(Path(write_mot(records, out / "mot", name=out.name or "usdcrowd",
                                                  fps=fps / stride, images=pngs)).parent.parent)
        outputs["coco"] = write_coco(records, out / "coco.json", [os.path.relpath(p, out) for p in pngs])
    outputs["contact_sheet"] = contact_sheet(pngs, records, out / "contact_sheet.png")
    if mp4:
        from PIL import Image

        from .colour import write_mp4

        def rgb(path):
            with Image.open(path) as im:
                return np.asarray(im.convert("RGB"))

        outputs["mp4"] = write_mp4([rgb(p) for p in pngs], out / "render.mp4", fps=fps / stride)
    return outputs
