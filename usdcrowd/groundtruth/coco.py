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
    """Write the COCO file of a sequence atomically; returns its path.

    The annotations are written as they are made (the document of a long
    sequence is never whole in memory); the images, a small entry per
    frame, follow them. ``records`` may read its frames from disk
    (:class:`.frame_json.Records`).
    """
    def dump(value):
        return json.dumps(value, separators=(",", ":"))

    images = []
    with atomic_path(path) as tmp:
        with open(tmp, "w") as f:
            f.write(f'{{"info":{dump(INFO)},"licenses":[],"categories":{dump(_categories(records))},"annotations":[')
            first = True
            for kind, entry in _entries(records, image_files):
                if kind == "image":
                    images.append(entry)
                    continue
                f.write(("" if first else ",") + dump(entry))
                first = False
            f.write(f'],"images":{dump(images)}}}')
    return os.fspath(path)
