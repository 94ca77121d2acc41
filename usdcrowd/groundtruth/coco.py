"""COCO export: instances with RLE masks and person keypoints, one file per sequence.

- ``images``: one per frame (``file_name`` is the display PNG relative to the
  COCO file, ``frame_index`` and ``time_code`` added);
- ``annotations``: one per visible agent (at least one pixel in the id pass):
  ``segmentation`` is the compressed RLE of its id-pass pixels (pycocotools;
  without it, COCO's uncompressed RLE, which pycocotools reads as well),
  ``area`` their count, ``bbox`` their tight box (COCO boxes enclose the
  mask), ``keypoints`` ``[x, y, v] * k`` with COCO's flags (0 not in image,
  1 occluded, 2 visible) and ``num_keypoints`` the labelled ones (v > 0),
  ``track_id`` and ``visibility`` added, ``iscrowd`` 0;
- ``categories``: ``person`` with the skeleton's keypoint names and its
  edges (1-based, as COCO), plus one category per other character type.
"""

from __future__ import annotations

import json
import os

from ..atomic import atomic_path

# Edges between rig.KEYPOINT_NAMES (pelvis, waist, neck, headTop, ground), 1-based.
SKELETON = [[5, 1], [1, 2], [2, 3], [3, 4]]
CATEGORIES = ("human", "herbivore", "ant", "bird")
CATEGORY_NAMES = {"human": "person"}


def _mask_utils():
    """pycocotools.mask, or None (then masks stay uncompressed RLE)."""
    try:
        from pycocotools import mask as mask_utils
    except ImportError:
        return None
    return mask_utils


def _categories(records) -> list[dict]:
    names = records[0]["keypoint_names"] if len(records) else []
    return [{"id": k + 1, "name": CATEGORY_NAMES.get(c, c), "supercategory": "agent",
             "keypoints": list(names), "skeleton": SKELETON} for k, c in enumerate(CATEGORIES)]


def _entries(records, image_files):
    """("image", dict) and ("annotation", dict) items of a sequence, a frame at a time."""
    mask_utils = _mask_utils()
    cat_id = {c: k + 1 for k, c in enumerate(CATEGORIES)}
    count = 0
    for index, (rec, file_name) in enumerate(zip(records, image_files), start=1):
        yield "image", {"id": index, "file_name": file_name, "width": rec["width"], "height": rec["height"],
                        "frame_index": index, "time_code": rec["time"], "camera": rec["camera"]["camera"]}
        for a in rec["agents"]:
            if a["visible_pixels"] == 0:
                continue
            seg = a["segmentation"]
            if mask_utils is not None:
                seg = mask_utils.frPyObjects(seg, *seg["size"])
                seg["counts"] = seg["counts"].decode("ascii")
            kps = [v for k in a["keypoints"] for v in (round(k[0], 2), round(k[1], 2), int(k[2]))]
            count += 1
            yield "annotation", {
                "id": count, "image_id": index,
                "category_id": cat_id.get(a.get("character_type", "human"), 1),
                "segmentation": seg, "area": int(a["visible_pixels"]), "bbox": a["bbox_visible"],
                "iscrowd": 0, "keypoints": kps, "num_keypoints": sum(1 for k in a["keypoints"] if k[2] > 0),
                "track_id": a["track_id"], "visibility": a["visibility"], "bbox_amodal": a["bbox_amodal"]}


INFO = {"description": "usdcrowd synthetic crowd ground truth", "version": "1.0"}


def coco_dict(records, image_files: list[str]) -> dict:
    """The COCO document of a sequence, in memory.

    Parameters
    ----------
    records : sequence of dict
        Frame records in sequence order.
    image_files : list of str
        File name of each frame's image, relative to the COCO file.
    """
    doc = {"info": INFO, "licenses": [], "images": [], "annotations": [], "categories": _categories(records)}
    for kind, entry in _entries(records, image_files):
        doc[kind + "s"].append(entry)
    return doc


def write_coco(records, path, image_files: list[str]) -> str:
    """Write the COCO file of a sequence atomically; returns its path (:func:`write_videos`, one video)."""
    return write_videos(path, [{"records": records, "images": image_files}], video_ids=False)


def compresses_masks() -> bool:
    """Whether masks are written as COCO's compressed RLE (pycocotools is installed)."""
    return _mask_utils() is not None


def write_videos(path, videos: list[dict], video_ids: bool = True) -> str:
    """Write the COCO file of one or more videos atomically, as it is read: the annotations are written
    as they are made (a long sequence, or a dataset's split, is never whole in memory); the images, a
    small entry per frame, follow them. The one COCO writer of the package.

    Parameters
    ----------
    videos : list of dict
        ``records`` (frame records in order; they may read their frames from disk,
        :class:`.frame_json.Records`), ``images`` (each frame's image file, relative to the COCO
        file) and, with ``video_ids``, the fields to list under ``videos`` (sequence, camera, fps...).
    video_ids : bool
        Number images and annotations across the videos and add ``video_id``, ``frame_id`` and
        ``instance_id`` (a track of one video), with a ``videos`` list: the layout of a dataset's
        split. Without it, one video's file as a sequence's render writes it.
    """
    def dump(value):
        return json.dumps(value, separators=(",", ":"))

    categories = next((_categories(v["records"]) for v in videos if len(v["records"])), _categories([]))
    images, listed = [], []
    image_base = annotation_id = 0
    with atomic_path(path) as tmp, open(tmp, "w") as f:
        f.write(f'{{"info":{dump(INFO)},"licenses":[],'
                + ('"annotations":[' if video_ids else f'"categories":{dump(categories)},"annotations":['))
        first = True
        for vid, video in enumerate(videos, start=1):
            n = 0
            for kind, entry in _entries(video["records"], video["images"]):
                if kind == "image":
                    n += 1
                    if video_ids:
                        entry = dict(entry, id=image_base + entry["id"], video_id=vid, frame_id=entry["frame_index"])
                    images.append(entry)
                    continue
                annotation_id += 1
                if video_ids:
                    entry = dict(entry, id=annotation_id, image_id=image_base + entry["image_id"], video_id=vid,
                                 instance_id=vid * 1_000_000 + int(entry["track_id"]))
                f.write(("" if first else ",") + dump(entry))
                first = False
            image_base += n
            listed.append({"id": vid, **{k: v for k, v in video.items() if k not in ("records", "images")},
                           "length": n})
        f.write(f'],"images":{dump(images)}'
                + (f',"videos":{dump(listed)},"categories":{dump(categories)}' if video_ids else "") + "}")
    return os.fspath(path)
