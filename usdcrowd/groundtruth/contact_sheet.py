"""A contact sheet: a grid of display frames with every agent's boxes and track id drawn on.

Solid box: the visible (id-pass) box; thin box: the amodal (projected-mesh)
box; the label is the track id and visibility in percent, drawn only on
boxes tall enough to carry it (a 200-agent crowd would be a smear of
text). Colours follow the track id so one agent keeps its colour across
frames.
"""

from __future__ import annotations

import colorsys
import os

import numpy as np

from ..atomic import atomic_path

# Boxes shorter than this (pixels on the sheet) get no text label.
LABEL_MIN_HEIGHT = 24


def track_colour(track_id: int) -> tuple[int, int, int]:
    """A stable, saturated colour for a track id (golden-ratio hue steps)."""
    r, g, b = colorsys.hsv_to_rgb((track_id * 0.618033988749895) % 1.0, 0.85, 1.0)
    return int(r * 255), int(g * 255), int(b * 255)


def draw_annotations(image, record: dict, scale: float = 1.0):
    """Draw the record's boxes and ids on a PIL image in place."""
    from PIL import ImageDraw

    draw = ImageDraw.Draw(image)
    for a in record["agents"]:
        col = track_colour(a["track_id"])
        if a.get("bbox_amodal"):
            x, y, w, h = (v * scale for v in a["bbox_amodal"])
            draw.rectangle([x, y, x + w, y + h], outline=col, width=1)
        if a.get("bbox_visible"):
            x, y, w, h = (v * scale for v in a["bbox_visible"])
            draw.rectangle([x, y, x + w, y + h], outline=col, width=2)
            if h >= LABEL_MIN_HEIGHT:
                draw.text((x + 2, max(0, y - 11)), f"{a['track_id']} {100 * a['visibility']:.0f}%", fill=col)


def contact_sheet(images: list[str], records: list[dict], out_png, columns: int = 4, thumb_width: int = 480,
                  max_frames: int = 16) -> str:
    """Write a grid of annotated frames.

    Parameters
    ----------
    images : list of path
        Display PNGs (sRGB), one per record.
    records : list of dict
        Frame records (see :mod:`.frame_json`).
    out_png : path-like
    columns : int
    thumb_width : int
        Width of each cell in pixels.
    max_frames : int
        At most this many frames, evenly spaced through the sequence.
    """
    from PIL import Image, ImageDraw

    n = len(images)
    if n == 0:
        raise ValueError("contact sheet of no frames")
    pick = np.unique(np.linspace(0, n - 1, min(n, max_frames)).round().astype(int))
    columns = min(columns, len(pick))
    rows = int(np.ceil(len(pick) / columns))
    with Image.open(images[pick[0]]) as first:
        scale = thumb_width / first.width
        cell_w, cell_h = thumb_width, int(round(first.height * scale))
    label_h = 16
    sheet = Image.new("RGB", (columns * cell_w, rows * (cell_h + label_h)), (20, 20, 20))
    for k, i in enumerate(pick):
        with Image.open(images[i]) as im:
            img = im.convert("RGB").resize((cell_w, cell_h), Image.LANCZOS)
        rec = records[i]
        draw_annotations(img, rec, scale)
        x, y = (k % columns) * cell_w, (k // columns) * (cell_h + label_h)
        sheet.paste(img, (x, y + label_h))
        ImageDraw.Draw(sheet).text((x + 4, y + 2), f"t={rec['time']:g}  {len(rec['agents'])} agents "
                                   f"({sum(a['visible_pixels'] > 0 for a in rec['agents'])} visible)",
                                   fill=(230, 230, 230))
    with atomic_path(out_png) as tmp:
        sheet.save(tmp, format="PNG")
    return os.fspath(out_png)
