"""A dataset's files in the field's layouts: MOTChallenge folders and seqmaps, COCO per split.

Layout of ``DATASET/`` (names relative to it)::

    mot/USDCROWD-<split>/<seq>-<camera>/     one MOTChallenge sequence per sequence and camera:
        gt/gt.txt, seqinfo.ini, frames.csv   (groundtruth.mot), img1/000001.png ...
        json/000001.json                     the per-frame JSON (social and camera-intent ground truth)
    mot/seqmaps/USDCROWD-<split>.txt          the sequences of each split (TrackEval's seqmaps)
    coco/<split>.json                        COCO instances of every video of the split
    sequences/<seq>/                         the sequence's stages and renders (see dataset.run)

TrackEval reads ``mot/`` as a MOTChallenge benchmark named ``USDCROWD``
(``GT_FOLDER=mot``, ``BENCHMARK=USDCROWD``, ``SPLIT_TO_EVAL=<split>``).
COCO's ``file_name`` is relative to ``DATASET/``; every image names its video
(``video_id``) and frame (``frame_id``), every annotation its video and
track (``track_id``, the agent's id; ``instance_id`` is unique in the file).
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from .. import guard
from ..atomic import atomic_path

BENCHMARK = "USDCROWD"


def mot_dir(root: Path, split: str) -> Path:
    return Path(root) / "mot" / f"{BENCHMARK}-{split}"


def video_name(sequence: str, camera_path: str) -> str:
    return f"{sequence}-{camera_path.rsplit('/', 1)[-1]}"


def link(src: str | os.PathLike, dst: Path) -> None:
    """``dst`` as a hard link to ``src`` (a copy across file systems), replacing what was there."""
    guard.make_dir(dst.parent)
    if dst.exists() or dst.is_symlink():
        guard.check_remove(dst)
        dst.unlink()
    try:
        os.link(src, dst)
    except OSError:
        shutil.copyfile(src, dst)


def write_mot_video(root: Path, split: str, name: str, records, pngs: list[str], jsons: list[str],
                    fps: float) -> Path:
    """One MOTChallenge sequence folder from a camera's frames; returns the folder."""
    from ..groundtruth.mot import write_mot

    folder = mot_dir(root, split) / name
    write_mot(records, folder, name=name, fps=fps, images=pngs)
    for i, src in enumerate(jsons, start=1):
        link(src, folder / "json" / f"{i:06d}.json")
    return folder


def write_seqmaps(root: Path, videos_by_split: dict[str, list[str]]) -> dict[str, str]:
    """TrackEval's seqmap of each split (a ``name`` header, then one sequence per line)."""
    out = {}
    for split, names in videos_by_split.items():
        path = Path(root) / "mot" / "seqmaps" / f"{BENCHMARK}-{split}.txt"
        guard.make_dir(path.parent)
        with atomic_path(path) as tmp:
            tmp.write_text("name\n" + "".join(f"{n}\n" for n in names))
        out[split] = os.fspath(path)
    return out


def write_split_coco(path: Path, videos: list[dict]) -> str:
    """COCO instances of a split, written as they are read (a split is never whole in memory).

    Parameters
    ----------
    path : Path
        ``DATASET/coco/<split>.json``.
    videos : list of dict
        ``name``, ``records`` (frame records, e.g. groundtruth.frame_json.Records),
        ``images`` (file names relative to DATASET/) and the video's fields to
        list under ``videos`` (sequence, camera, kind, fps...).

    Raises
    ------
    UsdcrowdError
        Without pycocotools (the masks are written as COCO's compressed RLE).
    """
    from ..groundtruth import coco

    if not coco.compresses_masks():
        from ..core.errors import UsdcrowdError

        raise UsdcrowdError("datasets write COCO's compressed RLE with pycocotools: "
                            "pip install 'usdcrowd[dataset]'")
    return coco.write_videos(path, videos, video_ids=True)
