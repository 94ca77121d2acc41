"""Make a dataset: plan every sequence, simulate and film them, render their frames, merge as results arrive.

Work comes in two kinds of task: *prepare* a sequence (scenario, simulation,
cameras: :func:`usdcrowd.dataset.scenario.prepare_sequence`) and *render* a
chunk of one camera's frames. Both run on an executor:

- ``inline``: in this process (debugging, tests);
- ``local``: ``workers`` processes on this machine (spawn context);
- ``ray``: Ray tasks, on a cluster at ``address`` or, without one, on a Ray
  instance started here for this run only (``ray.init(address="local")``:
  never a cluster the user did not name). On a multi-machine cluster the
  dataset folder must be on a file system every node mounts at the same path.

The driver alone writes the bookkeeping: each camera's render manifest
(:class:`usdcrowd.render.sequence.Manifest`: the files of every frame with
their sha256) as chunks finish, a camera's MOT folder when its last frame
is in, and the COCO files, seqmaps, dataset card and ``manifest.json``
(sha256 of every file) at the end. So a run killed at any point, run again
with the same command, prepares only the sequences without a ``plan.json``
for their plan and renders only the frames not recorded whole.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import time as _time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from .. import guard
from ..atomic import atomic_path, clean_partials, file_sha256, output_dir
from ..core.errors import UsdcrowdError
from . import layout
from .spec import DatasetSpec, assign_splits, draw_plan, load_spec

MANIFEST = "manifest.json"
# Frames per render task: enough to pay for building the scene in a worker
# (a second or two), few enough to spread a sequence over the workers.
CHUNK_FRAMES = 8
KINDS = ("steering", "static", "toric", "overview")


@dataclass
class DatasetResult:
    """What :func:`make_dataset` did and where the outputs are."""

    out_dir: str
    sequences: int
    videos: int
    frames: int
    rendered: int
    prepared: int
    seconds: float
    outputs: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)


# ------------------------------------------------------------------ workers
_CACHE: dict = {}


def prepare_task(plan: dict, spec_dict: dict, seq_dir: str) -> dict:
    """Worker side of a prepare task: the PreparedSequence as JSON."""
    import usdcrowd  # noqa: F401  (registers the schemas in a fresh worker)

    from .scenario import prepare_sequence, read_prepared

    made = read_prepared(Path(seq_dir), plan) is None
    return {**prepare_sequence(plan, DatasetSpec(**spec_dict), seq_dir).to_json(), "made": made}


def render_task(shot: str, camera: str, settings, times: list, out_dir: str, threads) -> list:
    """Worker side of a render task: render ``times`` of one camera; returns their manifest entries.

    The last camera's renderer is kept, so consecutive chunks of a camera build its scene once.
    """
    import usdcrowd  # noqa: F401

    from ..render.sequence import frame_renderer, render_frame_to_disk

    key = (shot, camera, repr(settings))
    if key not in _CACHE:
        from ..groundtruth.annotate import AgentMetadata
        from ..scenario.shot_scene import ShotScene

        _CACHE.clear()                        # one scene per worker at a time: bounded memory
        scene = ShotScene(shot)
        renderer = frame_renderer(scene, camera, settings, threads)
        _CACHE[key] = (renderer, AgentMetadata.from_shot(scene), settings)
    renderer, metadata, settings = _CACHE[key]
    return [render_frame_to_disk(renderer, metadata, float(t), out_dir, settings) for t in times]


# ---------------------------------------------------------------- executors
class _Done:
    """A finished task's result (hashable by identity, like a future)."""

    def __init__(self, value):
        self.value = value


class _Inline:
    """Runs each task when it is submitted."""

    threads = None

    def submit(self, fn, *args):
        return _Done(fn(*args))

    def wait(self, pending):
        return [(f, f.value) for f in pending], []

    def close(self, now: bool = False):
        pass


class _Local:
    def __init__(self, workers: int):
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        self.threads = max(1, (os.cpu_count() or 1) // workers)
        from ..interrupts import worker_ignores_interrupts

        self.pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"),
                                        initializer=worker_ignores_interrupts)

    def submit(self, fn, *args):
        from ..interrupts import children_deaf_to_ctrl_c

        with children_deaf_to_ctrl_c():     # the workers start on the first submit
            return self.pool.submit(fn, *args)

    def wait(self, pending):
        from concurrent.futures import FIRST_COMPLETED, wait

        done, rest = wait(pending, return_when=FIRST_COMPLETED)
        return [(f, f.result()) for f in done], list(rest)

    def close(self, now: bool = False):
        from ..interrupts import stop_pool

        if self.pool is None:
            return
        if now:
            import gc

            stop_pool(self.pool)
            self.pool = None
            gc.collect()            # the pool's queues' semaphores are released now, not warned about at exit
        else:
            self.pool.shutdown(cancel_futures=True)


class _Ray:
    def __init__(self, workers: int, address: str | None):
        try:
            import ray
        except ImportError:
            raise UsdcrowdError("--executor ray needs Ray: pip install 'usdcrowd[distributed]'") from None
        import logging

        self.ray = ray
        self.started = False
        if not ray.is_initialized():
            quiet = {"log_to_driver": False, "logging_level": logging.ERROR, "include_dashboard": False}
            if address:
                # A cluster's workers do not inherit this process's environment: hand them the guard's session.
                ray.init(address=address, runtime_env=guard.ray_runtime_env(), **quiet)
            else:
                # "local" starts a Ray instance for this run: never a cluster the user did not give.
                ray.init(address="local", num_cpus=max(workers, 1), **quiet)
            self.started = True
        # On a cluster Ray runs a task per CPU of each node: one render thread each, no oversubscription.
        self.threads = 1 if address else max(1, (os.cpu_count() or 1) // max(workers, 1))
        self.remote = {}
        self.submitted = set()             # the tasks not yet done (cancelled on Ctrl-C)

    def submit(self, fn, *args):
        if fn not in self.remote:
            self.remote[fn] = self.ray.remote(num_cpus=1)(fn)
        ref = self.remote[fn].remote(*args)
        self.submitted.add(ref)
        return ref

    def wait(self, pending):
        from ..render.sequence import _ray_result

        (ref,), rest = self.ray.wait(list(pending), num_returns=1)
        self.submitted.discard(ref)
        return [(ref, _ray_result(self.ray, ref))], list(rest)

    def close(self, now: bool = False):
        if self.started:
            self.ray.shutdown()
        elif now:                   # a cluster's workers: cancel this run's tasks, running or queued
            for ref in self.submitted:
                with contextlib.suppress(Exception):
                    self.ray.cancel(ref, force=True)


def _executor(kind: str, workers: int, address: str | None):
    if kind == "inline" or (kind == "local" and workers <= 0):
        return _Inline()
    if kind == "local":
        return _Local(workers)
    if kind == "ray":
        return _Ray(workers, address)
    raise UsdcrowdError(f"unknown executor {kind!r} (local, inline, ray)")


# ------------------------------------------------------------------- driver
def _settings(spec: DatasetSpec):
    from ..render.sequence import resolve_variant
    from ..render.settings import settings_from_preset

    settings = settings_from_preset(spec.preset, resolution=tuple(spec.resolution), spp=spec.spp,
                                    people_spp=spec.people_spp)
    # A dataset is its ground truth: on whatever the preset says (the preview preset has none).
    settings.ground_truth = True
    settings.aovs = settings.aovs or ("depth", "id")
    return resolve_variant(settings)


# Folders from the dataset's top to a camera's frames (sequences/<seq>/render/<camera>/exr).
DEPTH = 5


def _check_existing(out: Path, spec: DatasetSpec, force: bool) -> None:
    """Refuse to mix two specs in one dataset, unless asked to re-make what the new spec changes."""
    try:
        old = json.loads((out / MANIFEST).read_text())
    except (OSError, ValueError):
        return
    made = (out / "sequences").is_dir() and any((out / "sequences").iterdir())
    if old.get("state") == "in progress" and not made:
        return                  # an earlier run that failed before making anything: nothing to mix with
    if old.get("spec_sha256") not in (None, spec.digest()) and not force:
        raise UsdcrowdError(f"this dataset was made from another spec (sha256 {old['spec_sha256'][:12]}, "
                            f"now {spec.digest()[:12]}); give --force to re-make what the new one changes",
                            file=os.fspath(out / MANIFEST))


class _Run:
    """What a dataset run has done so far: the sequences filmed, each camera's frames still to render
    and its manifest, the cameras whose videos are written, the tasks in flight."""

    def __init__(self, out: Path, plans: dict, settings, bar, ex, guess: dict, n_sequences: int):
        self.out, self.plans, self.settings, self.bar, self.ex, self.guess = out, plans, settings, bar, ex, guess
        self.n_sequences = n_sequences
        self.prepared: dict[int, object] = {}
        self.cams: dict[tuple, dict] = {}           # (seq index, camera) -> manifest, remaining count
        self.pending: dict = {}
        self.written: set = set()                   # (sequence, camera) whose MOT folder is written
        self.notes: list[str] = []
        self.rendered = self.n_prepared = 0

    def status(self) -> None:
        self.bar.set_postfix_str(f"sequences {len(self.prepared)}/{self.n_sequences} filmed, "
                                 f"{len(self.written)}/{max(len(self.cams), 1)} cameras done")

    def prepared_one(self, i: int, result: dict) -> None:
        """A sequence is filmed: its cameras' frames still to render go out in chunks."""
        from ..render.sequence import Manifest, verify_frame
        from .scenario import PreparedSequence

        self.n_prepared += bool(result.pop("made"))
        seq = PreparedSequence(**result)
        self.prepared[i] = seq
        self.notes += [f"{seq.name}: {n}" for n in seq.notes]
        self.bar.total += (len(seq.cameras) - self.guess[i]) * len(seq.frames)
        for camera, _kind in seq.cameras:
            cam_out = camera_dir(self.out, seq.name, camera)
            guard.make_dir(cam_out)
            manifest = Manifest(cam_out, _render_header(seq, camera, self.plans[i], self.settings))
            todo = [t for t in seq.frames if not verify_frame(cam_out, t, manifest, self.settings)]
            self.bar.update(len(seq.frames) - len(todo))
            self.cams[(i, camera)] = {"manifest": manifest, "left": len(todo)}
            for k in range(0, len(todo), CHUNK_FRAMES):
                chunk = todo[k:k + CHUNK_FRAMES]
                self.pending[self.ex.submit(render_task, seq.shot, camera, self.settings, chunk,
                                            os.fspath(cam_out), self.ex.threads)] = ("render", i, camera)
            if not todo:
                self._camera_done(i, camera)

    def rendered_some(self, i: int, camera: str, entries: list) -> None:
        """A chunk of frames is in; a camera whose last frame is in is merged now."""
        state = self.cams[(i, camera)]
        for entry in entries:
            state["manifest"].add(entry)
        state["left"] -= len(entries)
        self.rendered += len(entries)
        self.bar.update(len(entries))
        if state["left"] == 0:
            self._camera_done(i, camera)

    def _camera_done(self, i: int, camera: str) -> None:
        self.cams[(i, camera)]["manifest"].flush()
        write_video(self.out, self.prepared[i], camera)
        self.written.add((self.prepared[i].name, camera))


def make_dataset(spec_path, out_dir, executor: str = "local", workers: int = 1, address: str | None = None,
                 progress: bool = True, force: bool = False, only: list[int] | None = None) -> DatasetResult:
    """Make (or finish) the dataset a spec describes in ``out_dir``.

    Parameters
    ----------
    spec_path : path-like
        The TOML spec (:mod:`usdcrowd.dataset.spec`).
    out_dir : path-like
    executor : {"local", "inline", "ray"}
    workers : int
        Processes (local) or concurrent tasks (a Ray instance started here).
    address : str, optional
        A Ray cluster's address (``ray`` only).
    progress : bool
        A bar over every frame of every camera, with rate and time left.
    force : bool
        Accept a spec that differs from the one the dataset was made from:
        sequences whose plan changed are made again, the others kept.
    only : list of int, optional
        Make only these sequences (re-making one alone). The merged files
        cover every sequence made so far; the manifest says "partial" until all are.

    Returns
    -------
    DatasetResult
    """
    from tqdm import tqdm

    t0 = _time.perf_counter()
    spec = load_spec(spec_path)
    indices = _chosen_sequences(spec, executor, address, only)
    settings = _settings(spec)
    out, all_plans, plans = _open_dataset(spec, out_dir, indices, progress, force, only)

    # Cameras per sequence before preparing: every one planned (a toric camera may turn out impossible).
    guess = {i: p["steering"] + len(p["static"]) + bool(p["toric"]) + bool(p["overview"]) for i, p in plans.items()}
    bar = tqdm(total=sum(guess[i] * spec.frames for i in indices), unit="frame", desc="dataset",
               disable=not progress, dynamic_ncols=True, smoothing=0.1)
    ex = _executor(executor, workers, address)
    run = _Run(out, plans, settings, bar, ex, guess, n_sequences=len(indices))
    clear_merged(out)
    _run_tasks(run, spec, indices)
    return _result(run, spec, all_plans, t0)


def _chosen_sequences(spec: DatasetSpec, executor: str, address: str | None, only: list[int] | None) -> list[int]:
    """The sequence indices to make, sorted; refuses an address without Ray and indices the spec lacks."""
    if address and executor != "ray":
        raise UsdcrowdError("--address is a Ray cluster's: give it with --executor ray")
    indices = list(range(spec.sequences)) if only is None else sorted(set(only))
    bad = [i for i in indices if not 0 <= i < spec.sequences]
    if bad:
        raise UsdcrowdError(f"no sequence {bad[0]}: the spec has {spec.sequences} (0 to {spec.sequences - 1})")
    return indices


def _open_dataset(spec: DatasetSpec, out_dir, indices: list[int], progress: bool, force: bool,
                  only: list[int] | None) -> tuple[Path, dict, dict]:
    """The dataset folder cleaned and marked "in progress" for this spec, with all plans and those to make."""
    from tqdm import tqdm

    out = output_dir(out_dir, "dataset")
    clean_partials(out, depth=DEPTH)        # frames in flight when an earlier run was stopped
    _check_existing(out, spec, force)
    splits = assign_splits(spec)
    drawing = tqdm(range(spec.sequences), unit="plan", desc="dataset plans", leave=False,
                   disable=not progress or spec.sequences < 2000)
    all_plans = {i: draw_plan(spec, i, splits[i]) for i in drawing}
    plans = {i: all_plans[i] for i in indices}
    if force and only is None:
        _drop_stale(out, {p["name"] for p in plans.values()})
    if Path(spec.path) != (out / "spec.toml").resolve():
        with atomic_path(out / "spec.toml") as tmp:
            shutil.copyfile(spec.path, tmp)
    _write_manifest(out, spec, all_plans, state="in progress")
    return out, all_plans, plans


def _run_tasks(run: _Run, spec: DatasetSpec, indices: list[int]) -> None:
    """Prepare and render the sequences of ``indices`` as results arrive; on any exit keep the frames in."""
    ex, out = run.ex, run.out
    try:
        spec_dict = asdict(spec)
        for i in indices:
            seq_dir = out / "sequences" / run.plans[i]["name"]
            run.pending[ex.submit(prepare_task, run.plans[i], spec_dict, os.fspath(seq_dir))] = ("prepare", i)
        while run.pending:
            finished, _ = ex.wait(list(run.pending))
            for fut, result in finished:
                what = run.pending.pop(fut)
                if what[0] == "prepare":
                    run.prepared_one(what[1], result)
                else:
                    run.rendered_some(what[1], what[2], result)
                run.status()
    except BaseException:
        ex.close(now=True)          # Ctrl-C, kill or an error: stop the workers, drop the frames in flight
        clean_partials(out, depth=DEPTH)
        raise
    finally:
        for state in run.cams.values():
            state["manifest"].flush()
        ex.close()
        run.bar.close()


def _result(run: _Run, spec: DatasetSpec, all_plans: dict, t0: float) -> DatasetResult:
    """Merge every sequence made (by this run or earlier ones), write the final manifest, say what was done."""
    out, settings = run.out, run.settings
    prepared, written, notes, rendered, n_prepared = run.prepared, run.written, run.notes, run.rendered, run.n_prepared
    # Sequences made by earlier runs (with --sequences) belong to the dataset too.
    for i, plan in all_plans.items():
        if i not in prepared:
            seq = _finished(out, plan, settings)
            if seq is not None:
                prepared[i] = seq
    made = [prepared[i] for i in sorted(prepared)]
    outputs = merge(out, spec, made, written)
    frames = sum(len(s.frames) * len(s.cameras) for s in made)
    videos = sum(len(s.cameras) for s in made)
    complete = len(made) == spec.sequences
    outputs["manifest"] = _write_manifest(out, spec, all_plans, state="complete" if complete else "partial")
    if not complete:
        notes.append(f"{len(made)} of {spec.sequences} sequences are made: run without --sequences to finish")
    return DatasetResult(os.fspath(out), len(made), videos, frames, rendered, n_prepared,
                         _time.perf_counter() - t0, outputs, notes)


def _finished(out: Path, plan: dict, settings):
    """A sequence an earlier run made whole (filmed, every frame of every camera recorded), else None."""
    from ..render.sequence import MANIFEST as FRAMES_MANIFEST
    from ..render.sequence import frame_tag
    from .scenario import read_prepared

    seq = read_prepared(out / "sequences" / plan["name"], plan)
    if seq is None:
        return None
    for camera, _ in seq.cameras:
        try:
            doc = json.loads((camera_dir(out, seq.name, camera) / FRAMES_MANIFEST).read_text())
        except (OSError, ValueError):
            return None
        if doc.get("header") != _render_header(seq, camera, plan, settings):
            return None
        if not all(frame_tag(t) in doc.get("frames", {}) for t in seq.frames):
            return None
    return seq


def camera_dir(out: Path, sequence: str, camera: str) -> Path:
    """Where one camera of a sequence renders its frames: ``sequences/<seq>/render/<camera name>/``."""
    return Path(out) / "sequences" / sequence / "render" / camera.rsplit("/", 1)[-1]


def _render_header(seq, camera: str, plan: dict, settings) -> dict:
    """A camera's render manifest header: its frames count only for this shot, camera, plan and settings."""
    return {"shot": seq.shot, "camera": camera, "plan": plan["digest"], "settings": settings.fingerprint()}


def _drop_stale(out: Path, keep: set[str]) -> None:
    """Sequence folders of an older spec that the new one no longer has."""
    root = out / "sequences"
    if root.is_dir():
        for d in root.iterdir():
            if d.is_dir() and d.name not in keep:
                guard.check_remove(d)
                shutil.rmtree(d)


def _video_files(out: Path, seq, camera: str):
    """(png paths, json paths, frame records, fps) of one camera of a sequence, from its frames on disk."""
    from ..groundtruth import frame_json
    from ..render.sequence import frame_files

    cam_out = camera_dir(out, seq.name, camera)
    pngs = [os.fspath(cam_out / frame_files(t, False)["png"]) for t in seq.frames]
    jsons = [os.fspath(cam_out / frame_files(t, True)["json"]) for t in seq.frames]
    stride = float(np.median(np.diff(seq.frames))) if len(seq.frames) > 1 else 1.0
    return pngs, jsons, frame_json.Records(jsons), _fps(seq.shot) / stride


def write_video(out: Path, seq, camera: str) -> Path:
    """One camera's MOTChallenge folder and contact sheet, as soon as its last frame is in."""
    from ..groundtruth.contact_sheet import contact_sheet

    pngs, jsons, records, fps = _video_files(out, seq, camera)
    folder = layout.write_mot_video(out, seq.split, layout.video_name(seq.name, camera), records, pngs, jsons, fps)
    contact_sheet(pngs, records, Path(pngs[0]).parent.parent / "contact_sheet.png")
    return folder


def clear_merged(out: Path) -> None:
    """The merged files are rebuilt from the frames on every run: nothing stale survives a changed spec.

    Only what the merge writes goes (MOT's split folders and seqmaps, COCO's split files): anything else
    a user put in ``mot/`` or ``coco/`` stays.
    """
    from .spec import SPLITS

    merged = [path for split in SPLITS for path in (
        layout.mot_dir(out, split), out / "mot" / "seqmaps" / f"{layout.BENCHMARK}-{split}.txt",
        out / "coco" / f"{split}.json")]
    for path in merged:
        if path.is_dir() and not path.is_symlink():
            guard.check_remove(path)
            shutil.rmtree(path)
        elif path.exists():
            guard.check_remove(path)
            path.unlink()


def merge(out: Path, spec: DatasetSpec, sequences: list, written: set) -> dict:
    """Seqmaps, COCO per split and the dataset card (and the MOT folders not ``written`` yet)."""
    from .card import CardStats, write_card

    stats = CardStats()
    by_split: dict[str, list] = {}
    names_by_split: dict[str, list] = {}
    for seq in sequences:
        stats.add_sequence(seq)
        for camera, kind in seq.cameras:
            name = layout.video_name(seq.name, camera)
            if (seq.name, camera) not in written:
                write_video(out, seq, camera)
            folder = layout.mot_dir(out, seq.split) / name
            _, _, records, fps = _video_files(out, seq, camera)
            stats.add_video(kind, records)
            names_by_split.setdefault(seq.split, []).append(name)
            by_split.setdefault(seq.split, []).append({
                "name": name, "sequence": seq.name, "camera": camera, "kind": kind, "fps": fps,
                "records": records,
                "images": [os.path.relpath(folder / "img1" / f"{k:06d}.png", out) for k in range(1, len(records) + 1)]})
    outputs = {"mot": os.fspath(out / "mot")}
    outputs.update({f"seqmap_{k}": v for k, v in layout.write_seqmaps(out, names_by_split).items()})
    for split, videos in by_split.items():
        outputs[f"coco_{split}"] = layout.write_split_coco(out / "coco" / f"{split}.json", videos)
    outputs.update(write_card(out, spec, stats))
    return outputs


def _fps(shot: str) -> float:
    from pxr import Sdf

    layer = Sdf.Layer.FindOrOpen(shot)
    return float(layer.timeCodesPerSecond) if layer else 24.0


def _write_manifest(out: Path, spec: DatasetSpec, plans: dict, state: str) -> str:
    """``manifest.json``: the spec's sha256, every plan, and (when complete) sha256 of every file.

    Frame files take the digests their render manifests recorded as they were
    written; the rest are read once here.
    """
    doc = {"spec_sha256": spec.digest(), "spec": spec.canonical(), "state": state,
           "plans": {p["name"]: p for p in plans.values()}}
    if state != "in progress":
        # By inode: MOT's img1/ and json/ are hard links to the frames, whose digests are known.
        recorded = {}
        for manifest in (out / "sequences").glob("*/render/*/manifest.json"):
            frames = json.loads(manifest.read_text()).get("frames", {})
            for entry in frames.values():
                for rel, rec in entry["files"].items():
                    st = (manifest.parent / rel).stat()
                    if st.st_size == rec["size"]:
                        recorded[(st.st_dev, st.st_ino)] = rec
        files = {}
        for path in sorted(p for p in out.rglob("*") if p.is_file() and p.name != MANIFEST
                           and not p.name.endswith(".partial")):
            st = path.stat()
            rec = recorded.get((st.st_dev, st.st_ino))
            if rec is None or st.st_size != rec["size"]:
                rec = {"size": st.st_size, "sha256": file_sha256(path)}
            files[os.fspath(path.relative_to(out))] = {"size": rec["size"], "sha256": rec["sha256"]}
        doc["files"] = files
    path = out / MANIFEST
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(doc, indent=1, sort_keys=True))
    return os.fspath(path)
