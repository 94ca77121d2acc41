"""Where preview frames go: PNG files, a contact sheet, an MP4.

Every file is written whole or not at all (:func:`usdcrowd.atomic.atomic_path`).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ...atomic import atomic_path, output_dir
from ...core.errors import UsdcrowdError

_PIP_HINT = "install usdcrowd[preview] (pip install 'usdcrowd[preview]')"


def write_png(image: np.ndarray, path: str | os.PathLike) -> str:
    """Write an (h, w, 3) or (h, w) uint8 image as PNG; returns the path."""
    from PIL import Image

    with atomic_path(path) as tmp:
        Image.fromarray(np.ascontiguousarray(image)).save(tmp, format="PNG")
    return os.fspath(path)


def write_aovs(ids: np.ndarray, depth: np.ndarray, path: str | os.PathLike) -> str:
    """Write the id (uint32) and depth (float32, metres, inf on background) buffers to one .npz."""
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            np.savez_compressed(fh, ids=ids, depth=depth)
    return os.fspath(path)


def contact_sheet(images: list[np.ndarray], labels: list[str] | None = None, columns: int = 4,
                  thumb_width: int = 320, gap: int = 4) -> np.ndarray:
    """Tile frames into one picture, each with an optional label.

    Parameters
    ----------
    images : list of (h, w, 3) uint8
        Frames of one size.
    labels : list of str, optional
        Drawn in each tile's corner (e.g. the time code).
    columns : int
    thumb_width : int
        Width of a tile in pixels (aspect kept).

    Returns
    -------
    (H, W, 3) uint8
    """
    from PIL import Image, ImageDraw

    if not images:
        raise UsdcrowdError("no frames for a contact sheet")
    h, w = images[0].shape[:2]
    tw = int(min(thumb_width, w))
    th = max(1, int(round(h * tw / w)))
    columns = max(1, min(columns, len(images)))
    rows = -(-len(images) // columns)
    sheet = Image.new("RGB", (columns * tw + (columns + 1) * gap, rows * th + (rows + 1) * gap), (24, 24, 24))
    draw = ImageDraw.Draw(sheet)
    for k, img in enumerate(images):
        r, c = divmod(k, columns)
        x, y = gap + c * (tw + gap), gap + r * (th + gap)
        sheet.paste(Image.fromarray(np.ascontiguousarray(img)).resize((tw, th), Image.BILINEAR), (x, y))
        if labels:
            draw.rectangle([x, y, x + 7 * len(labels[k]) + 6, y + 14], fill=(0, 0, 0))
            draw.text((x + 3, y + 1), labels[k], fill=(255, 255, 255))
    return np.asarray(sheet)


class Mp4Writer:
    """Frames to an H.264 MP4 through imageio-ffmpeg, renamed into place on close.

    Parameters
    ----------
    path : path-like
    fps : float
    quality : float
        imageio's 0-10 scale.
    """

    def __init__(self, path: str | os.PathLike, fps: float, quality: float = 8.0):
        try:
            import imageio.v2 as imageio
            import imageio_ffmpeg  # noqa: F401  (the ffmpeg binary comes with it)
        except ImportError as exc:
            raise UsdcrowdError(f"MP4 output needs imageio and imageio-ffmpeg ({exc}); {_PIP_HINT}") from None
        self.path = Path(path)
        self._ctx = atomic_path(self.path)
        tmp = self._ctx.__enter__()
        # yuv420p (what every player reads) needs even sizes: macro_block_size 2
        # pads at most one row/column instead of rescaling to multiples of 16.
        self._writer = imageio.get_writer(tmp, format="FFMPEG", mode="I", fps=float(fps), codec="libx264",
                                          quality=quality, pixelformat="yuv420p", macro_block_size=2,
                                          ffmpeg_log_level="error")

    def append(self, frame: np.ndarray) -> None:
        self._writer.append_data(np.ascontiguousarray(frame))

    def close(self, ok: bool = True) -> str:
        self._writer.close()
        if ok:
            self._ctx.__exit__(None, None, None)
        else:
            self._ctx.__exit__(RuntimeError, RuntimeError("aborted"), None)
        return os.fspath(self.path)

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        self._writer.close()
        try:
            self._ctx.__exit__(exc_type, exc, tb)
        except BaseException:
            if exc_type is None:
                raise
        return False


def sheet_frames(times: np.ndarray, n: int = 12) -> np.ndarray:
    """Up to ``n`` evenly spaced time codes from ``times`` for a contact sheet."""
    times = np.asarray(times)
    if len(times) <= n:
        return times
    return times[np.unique(np.round(np.linspace(0, len(times) - 1, n)).astype(int))]


def write_sequence(renderer, times: np.ndarray, camera: str | None, *, video=None, frames_dir=None,
                   aovs: bool = False, sheet=None, progress: bool = True) -> dict[str, str]:
    """Render ``times`` with ``renderer`` into a video and/or PNG frames, plus a contact sheet.

    Parameters
    ----------
    renderer : PreviewRenderer
    times : (t,) float
        Time codes.
    camera : str or None
        Camera prim path (None: the stage's first camera).
    video : path-like, optional
        MP4 to write (through a temporary name).
    frames_dir : path-like, optional
        Folder for ``frame.NNNN.png`` (and ``.npz`` ids/depth when ``aovs``).
    sheet : path-like, optional
        Contact sheet of up to 12 frames.

    Returns
    -------
    dict
        Paths written: ``mp4``, ``frames``, ``contact_sheet`` as applicable.
    """
    from tqdm import tqdm

    on_sheet = set(float(t) for t in sheet_frames(times))
    thumbs, labels, paths = [], [], {}
    if frames_dir is not None:
        output_dir(frames_dir, "preview")
        paths["frames"] = str(frames_dir)
    writer = Mp4Writer(video, renderer.scene.fps) if video is not None else None
    ok = False
    try:
        for t in tqdm(times, desc="preview", unit="frame", disable=not progress, leave=False):
            f = renderer.render(float(t), camera)
            if writer is not None:
                writer.append(f.color)
            if frames_dir is not None:
                stem = Path(frames_dir) / (f"frame.{int(round(t)):04d}" if float(t).is_integer() else f"frame.{t:09.3f}")
                write_png(f.color, f"{stem}.png")
                if aovs:
                    write_aovs(f.ids, f.depth, f"{stem}.npz")
            if float(t) in on_sheet:
                thumbs.append(f.color)
                labels.append(f"{t:g}")
        ok = True
    finally:
        if writer is not None:
            closed = writer.close(ok)
            if ok:
                paths["mp4"] = closed
    if sheet is not None:
        paths["contact_sheet"] = write_png(contact_sheet(thumbs, labels), sheet)
    return paths


def render_shot(shot_path, out_dir, *, camera=None, resolution=(640, 360), frames=None, progress: bool = True,
                mp4: bool = True, max_frames: int = 48) -> dict[str, str]:
    """Render a preview MP4 and a contact sheet of a shot into ``out_dir``.

    Parameters
    ----------
    shot_path : path-like
    out_dir : path-like
    camera : str, optional
    resolution : (int, int)
    frames : array of time codes, optional
        Default: the stage's range, at most ``max_frames`` of it from the start.
    progress : bool
        tqdm bar.

    Returns
    -------
    dict
        ``{"mp4": ..., "contact_sheet": ...}``.
    """
    from .renderer import PreviewRenderer

    out = Path(out_dir)
    output_dir(out, "preview")
    r = PreviewRenderer(shot_path, *resolution)
    try:
        times = np.asarray(frames) if frames is not None else r.scene.time_codes[:max_frames]
        return write_sequence(r, times, camera, video=out / "preview.mp4" if mp4 else None,
                              sheet=out / "preview_sheet.png", progress=progress)
    finally:
        r.release()


def camera_gallery(shot_path, out_png, cameras: list[str], times: np.ndarray, resolution=(480, 270),
                   progress: bool = True) -> str:
    """A contact sheet with one row per camera and one column per time code.

    Each tile is labelled with the camera's name, the frame and, for camera
    agents, what the camera was doing (``crowd:camera:state`` and the event
    it tracked).
    """
    from tqdm import tqdm

    from .renderer import PreviewRenderer

    r = PreviewRenderer(shot_path, *resolution)
    try:
        thumbs, labels = [], []
        with tqdm(total=len(cameras) * len(times), desc="gallery", unit="frame", disable=not progress,
                  leave=False) as bar:
            for cam in cameras:
                prim = r.scene.stage.GetPrimAtPath(cam)
                state = prim.GetAttribute("crowd:camera:state") if prim else None
                tracked = prim.GetAttribute("crowd:camera:trackedEvent") if prim else None
                for t in times:
                    thumbs.append(r.render(float(t), cam).color)
                    label = f"{cam.rsplit('/', 1)[-1]} {t:g}"
                    if state and state.HasValue():
                        event = (tracked.Get(float(t)) or "").rsplit("/", 1)[-1] if tracked else ""
                        label += f" {state.Get(float(t))}" + (f" {event}" if event else "")
                    labels.append(label)
                    bar.update(1)
    finally:
        r.release()
    return write_png(contact_sheet(thumbs, labels, columns=len(times), thumb_width=resolution[0]), out_png)
