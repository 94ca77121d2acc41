"""2D poses of a film clip's two main characters (seed 002, section 4 and appendix B).

Per frame, a pose detector finds people; the two main characters are kept,
associated over time, and their missing frames filled, giving the joints
:mod:`usdcrowd.cameras.estimator` reads (:data:`~usdcrowd.cameras.estimator.JOINTS`,
in the NDC of a camera with usdcrowd's lens, see :func:`to_ndc`).

The detector is MediaPipe's BlazePose (the ``video`` extra: ``mediapipe``
0.10.14, whose wheel bundles the person detector and the landmark model,
so nothing downloads at run time). It finds one person per call: a second
is found by painting the first out and looking again (the paper's LCR-Net
finds several at once). People too small for the detector's view of the
whole frame (long shots) are looked for again in a crop around where they
were last found, as BlazePose's own tracking does for one person.
Association follows appendix B: each frame's people go to the two
characters by the L2 distance between their joints and the characters'
last known ones (in body sizes), and, beyond the paper, by what they wear
(the colour of the torso: a camera craning over a pair brings one where
the other was last seen, and the joints alone then swap them); A is the
character on the left of the first frame where both are seen (the reader
then makes the main character A, the larger on screen, as appendix B
picks it). Frames where a character is not found are filled by linear
interpolation, over any gap (the paper fills gaps under 3 frames and
rejects a clip with longer ones; here a clip is refused when
fewer than :data:`MIN_FOUND` of its frames show both).
"""

from __future__ import annotations

import contextlib
import os
import sys
import warnings
from pathlib import Path

import numpy as np

VIDEO_SUFFIXES = (".mp4", ".mov", ".avi", ".mkv", ".webm", ".m4v")
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")
MIN_FOUND = 0.5         # share of frames that must show both characters
MEDIAPIPE = "mediapipe==0.10.14"
# BlazePose landmark indices of the estimator's joints: the head is the ears' midpoint, the neck the
# shoulders', the hip centre the hips'.
_NOSE, _EARS, _SHOULDERS, _HIPS = 0, (7, 8), (11, 12), (23, 24)
_PAINT_MARGIN = 0.15    # of the person's landmark box, around it, painted out before looking again
_CROP = 2.0             # a crop around a person last found is this many times the larger side of their box
_CROP_MIN = 96          # pixels: the smallest crop side (the detector's input is 224 pixels)
_COLOUR_WEIGHT = 5.0    # association: torso colours 0.2 apart (RGB in [0, 1]) cost as much as a body size apart
_COLOUR_MEMORY = 0.1    # how much each new sighting moves a character's remembered colour
_CROP_KEEP = 0.5        # a person found in a crop is kept if their head is within this share of the box's
                        # larger side from where the box's own head was


def is_clip(path) -> bool:
    """Whether ``path`` names a film clip (a video file, or a folder of frames) rather than a stage."""
    p = Path(path)
    return p.is_dir() or p.suffix.lower() in VIDEO_SUFFIXES


def read_frames(path):
    """(frames, fps): a clip's frames, each (h, w, 3) uint8, and its frame rate (None for a folder).

    Raises
    ------
    UsdcrowdError
        Not readable, or no frames.
    """
    from ..core.errors import UsdcrowdError

    p = Path(path)
    if p.is_dir():
        files = sorted(f for f in p.iterdir() if f.suffix.lower() in IMAGE_SUFFIXES)
        if not files:
            raise UsdcrowdError(f"the folder has no frames ({', '.join(IMAGE_SUFFIXES)})", file=str(p))
        from PIL import Image

        frames = []
        for f in files:
            try:
                frames.append(np.asarray(Image.open(f).convert("RGB")))
            except OSError as exc:
                raise UsdcrowdError(f"cannot read the frame: {exc}", file=str(f)) from None
        if len({fr.shape for fr in frames}) > 1:
            raise UsdcrowdError("the folder's frames are not all the same size", file=str(p))
        return frames, None
    try:
        import imageio.v2 as imageio
    except ImportError as exc:
        raise UsdcrowdError(f"reading a video needs imageio and imageio-ffmpeg ({exc}): "
                            "pip install 'usdcrowd[video]'") from None
    try:
        reader = imageio.get_reader(os.fspath(p), format="FFMPEG")
        fps = float(reader.get_meta_data().get("fps") or 0.0) or None
        frames = [np.asarray(f)[..., :3] for f in reader]
        reader.close()
    except Exception as exc:            # imageio and ffmpeg raise many kinds; the user's file is the cause
        raise UsdcrowdError(f"cannot read the video: {str(exc).splitlines()[0] if str(exc) else type(exc).__name__}",
                            file=str(p)) from None
    if not frames:
        raise UsdcrowdError("the video has no frames", file=str(p))
    return frames, fps


def to_ndc(xy_pixels: np.ndarray, width: int, height: int, focal_length: float, reference_fov_x: float,
           reference_aspect: float) -> np.ndarray:
    """(..., 2) NDC, in a camera of ``reference_fov_x`` and ``reference_aspect``, of pixel positions in a
    ``width`` x ``height`` frame shot with a ``focal_length`` mm lens (36 mm wide aperture): the paper's
    "linear transformation" to the training camera, through each pixel's ray."""
    from .behaviors import fov_y

    xy = np.asarray(xy_pixels, dtype=np.float64)
    half = 0.5 * 36.0 / focal_length                                   # tan of half the clip's horizontal view
    tx = (2.0 * xy[..., 0] / width - 1.0) * half
    ty = (1.0 - 2.0 * xy[..., 1] / height) * half * height / width
    return np.stack([tx / np.tan(0.5 * reference_fov_x), ty / np.tan(0.5 * fov_y(reference_fov_x, reference_aspect))],
                    -1)


def _joints_of_pixels(lm: np.ndarray) -> np.ndarray:
    """(8, 2) pixel positions of the estimator's joints from BlazePose's 33 landmarks ((33, 2) pixels)."""
    mid = lambda ij: 0.5 * (lm[ij[0]] + lm[ij[1]])  # noqa: E731
    # BlazePose's left and right are the person's own, as the estimator's joints are.
    return np.array([mid(_EARS), mid(_SHOULDERS), lm[11], lm[12], mid(_HIPS), lm[23], lm[24], lm[_NOSE]])


@contextlib.contextmanager
def _quiet_stderr():
    """Standard error closed at the file descriptor: MediaPipe's C++ side logs there (TensorFlow Lite's
    delegate, its graph) before any logging setting of its applies."""
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def paint_box(landmarks: np.ndarray, width: int, height: int) -> tuple[int, int, int, int] | None:
    """(x0, y0, x1, y1) pixels to paint out around a person's landmarks ((k, 2) pixels, some maybe off the
    frame: those within a tenth of the frame of it count), or None when none does."""
    xs, ys = np.asarray(landmarks, dtype=np.float64).T
    inside = (xs > -0.1 * width) & (xs < 1.1 * width) & (ys > -0.1 * height) & (ys < 1.1 * height)
    if not inside.any():
        return None
    xs, ys = xs[inside], ys[inside]
    mx, my = _PAINT_MARGIN * np.ptp(xs), _PAINT_MARGIN * np.ptp(ys)
    x0, x1 = int(max(xs.min() - mx, 0)), int(min(xs.max() + mx, width))
    y0, y1 = int(max(ys.min() - my, 0)), int(min(ys.max() + my, height))
    return (x0, y0, x1, y1) if x1 > x0 and y1 > y0 else None


def _side(joints: np.ndarray) -> float:
    """Pixels: the larger side of the box round a person's (8, 2) joints."""
    return float(np.ptp(joints, axis=0).max())


def crop_box(joints: np.ndarray, width: int, height: int) -> tuple[int, int, int, int]:
    """(x0, y0, x1, y1) pixels: a square :data:`_CROP` times the larger side of the box round a person's
    joints ((8, 2) pixels, ears to hips: the crop holds the whole body), centred on them, at least
    :data:`_CROP_MIN` pixels, shifted into the frame (clipped where the frame is smaller)."""
    centre = 0.5 * (joints.min(axis=0) + joints.max(axis=0))
    side = min(max(_CROP * _side(joints), _CROP_MIN), width, height)
    x0 = int(np.clip(centre[0] - 0.5 * side, 0, width - side))
    y0 = int(np.clip(centre[1] - 0.5 * side, 0, height - side))
    return x0, y0, x0 + int(side), y0 + int(side)


def _paint(image: np.ndarray, box) -> None:
    """Paint ``box`` (x0, y0, x1, y1) of ``image`` in place with the frame's mean colour."""
    x0, y0, x1, y1 = box
    image[y0:y1, x0:x1] = image.reshape(-1, 3).mean(axis=0).astype(np.uint8)


class _Detector:
    """MediaPipe's BlazePose on single images, up to two people per frame."""

    def __init__(self):
        from ..core.errors import UsdcrowdError

        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                from mediapipe.python.solutions import pose
        except ImportError as exc:
            raise UsdcrowdError(f"a video reference needs the pose detector ({exc}): pip install 'usdcrowd[video]' "
                                f"({MEDIAPIPE}; it pins protobuf < 5, so keep it in its own environment)") from None
        with _quiet_stderr():
            self._pose = pose.Pose(static_image_mode=True, model_complexity=1, min_detection_confidence=0.3)

    def _landmarks(self, image: np.ndarray):
        """BlazePose's 33 landmarks ((33, 2) pixels of ``image``) of one person, or None."""
        h, w = image.shape[:2]
        with warnings.catch_warnings(), _quiet_stderr():   # protobuf's deprecation notice, MediaPipe's logs
            warnings.simplefilter("ignore")
            res = self._pose.process(np.ascontiguousarray(image))
        if not res.pose_landmarks:
            return None
        return np.array([[p.x * w, p.y * h] for p in res.pose_landmarks.landmark])

    def people(self, image: np.ndarray, most: int = 2, last: list[np.ndarray] = ()) -> list[np.ndarray]:
        """Up to ``most`` people, each (8, 2) pixels: one found, painted out, and looked for again; then,
        while fewer than ``most``, in a crop around each of ``last`` (people found before, (8, 2) each)
        whose head is not near anyone's found here (:func:`crop_box`)."""
        h, w = image.shape[:2]
        image, found = image.copy(), []
        for _ in range(most):
            lm = self._landmarks(image)
            box = None if lm is None else paint_box(lm, w, h)
            if box is None:                 # nobody, or a person wholly off the frame: nothing to keep or paint
                break
            found.append(_joints_of_pixels(lm))
            _paint(image, box)
        for before in last:
            if len(found) >= most:
                break
            if any(np.linalg.norm(p[0] - before[0]) < _CROP_KEEP * _side(before) for p in found):
                continue                    # already found here
            x0, y0, x1, y1 = crop_box(before, w, h)
            lm = self._landmarks(image[y0:y1, x0:x1])
            if lm is None:
                continue
            joints = _joints_of_pixels(lm) + [x0, y0]
            if np.linalg.norm(joints[0] - before[0]) < _CROP_KEEP * _side(before):
                found.append(joints)
                box = paint_box(lm + [x0, y0], w, h)
                if box is not None:
                    _paint(image, box)
        return found

    def close(self):
        self._pose.close()


def torso_colours(frames, per_frame: list[list[np.ndarray]]) -> list[list[np.ndarray]]:
    """Each found person's clothing colour: (3,) RGB in [0, 1], the median of small patches on the torso
    (between the shoulders and the hips, (8, 2) pixel joints), NaN where none is in the frame."""
    out = []
    for image, people in zip(frames, per_frame):
        h, w = image.shape[:2]
        colours = []
        for p in people:
            # Three tenths and half of the way down from each shoulder and the neck towards the hips.
            tops, bottoms = p[[1, 2, 3]], p[[4, 5, 6]]
            pts = np.concatenate([tops + f * (bottoms - tops) for f in (0.3, 0.5)]).round().astype(int)
            r = max(1, int(0.03 * _side(p)))
            patches = [image[max(y - r, 0):y + r + 1, max(x - r, 0):x + r + 1].reshape(-1, 3)
                       for x, y in pts if 0 <= x < w and 0 <= y < h]
            colours.append(np.median(np.concatenate(patches), axis=0) / 255.0 if patches else np.full(3, np.nan))
        out.append(colours)
    return out


def associate(per_frame: list[list[np.ndarray]], colours: list[list[np.ndarray]] | None = None
              ) -> tuple[np.ndarray, np.ndarray]:
    """The two characters over time from each frame's people (each (8, 2)), and their torso colours if given
    (:func:`torso_colours`).

    Returns
    -------
    joints : (t, 2, 8, 2) float
        A's and B's joints (NaN where not found); A is the one on the left in
        the first frame with two people.
    found : (t, 2) bool
    """
    t = len(per_frame)
    joints = np.full((t, 2, 8, 2), np.nan)
    first = next((k for k, people in enumerate(per_frame) if len(people) >= 2), None)
    if first is None:
        return joints, np.zeros((t, 2), bool)
    pair = sorted(range(2), key=lambda i: per_frame[first][i][0, 0])       # indices of A and B
    joints[first] = [per_frame[first][i] for i in pair]
    order = list(range(first + 1, t)) + list(range(first - 1, -1, -1))
    colour_of = (lambda k, i: colours[k][i]) if colours is not None else (lambda k, i: np.full(3, np.nan))
    pair_colours = [colour_of(first, i) for i in pair]
    for k in order:
        if k in (first + 1, first - 1):          # from the first frame, forward and then back
            last, worn = [joints[first, 0], joints[first, 1]], list(pair_colours)
        people = per_frame[k]
        if not people:
            continue
        # Appendix B's L2 matching (in body sizes), and what each wears: a camera craning over a pair brings
        # one where the other was last seen, and the joints alone then swap them.
        cost = np.array([[np.linalg.norm(p - q) / max(_side(q), 1.0) for q in last] for p in people])
        for i in range(len(people)):
            for c in (0, 1):
                d = np.linalg.norm(colour_of(k, i) - worn[c])
                cost[i, c] += _COLOUR_WEIGHT * d if np.isfinite(d) else 0.0
        if len(people) >= 2:
            # The better of the two ways to give two people to A and B.
            given = dict(enumerate(min(((i, j) for i in range(len(people)) for j in range(len(people)) if i != j),
                                       key=lambda ij: cost[ij[0], 0] + cost[ij[1], 1])))   # character -> person
        else:
            given = {int(np.argmin(cost[0])): 0}
        for c, i in given.items():
            joints[k, c] = last[c] = people[i]
            new = colour_of(k, i)
            if np.isfinite(new).all():
                worn[c] = new if not np.isfinite(worn[c]).all() else worn[c] + _COLOUR_MEMORY * (new - worn[c])
    return joints, np.isfinite(joints).all(axis=(2, 3))


def fill(joints: np.ndarray, found: np.ndarray) -> np.ndarray:
    """(t, 2, 8, 2) joints with each character's missing frames interpolated linearly (ends held)."""
    out = joints.copy()
    frames = np.arange(len(joints))
    for c in (0, 1):
        have = found[:, c]
        if not have.any():
            continue
        flat = joints[:, c].reshape(len(joints), -1)
        out[:, c] = np.column_stack([np.interp(frames, frames[have], flat[have, k])
                                     for k in range(flat.shape[1])]).reshape(len(joints), 8, 2)
    return out


def main_character(joints: np.ndarray, found: np.ndarray) -> int:
    """0 or 1: which of the two characters is the main one (appendix B): the larger on screen, by the area of
    the box around its joints ((t, 2, 8, 2) NDC), on average over the frames where both were found."""
    size = np.ptp(joints, axis=2).prod(axis=-1)                     # (t, 2)
    both = found.all(axis=1)
    mean = size[both].mean(axis=0) if both.any() else size.mean(axis=0)
    return int(mean[1] > mean[0])


def detect(frames, tick=None) -> list[list[np.ndarray]]:
    """Each frame's people (up to two, each (8, 2) pixels); ``tick()`` is called after each frame."""
    detector = _Detector()
    per_frame, last = [], []
    try:
        for image in frames:
            people = detector.people(image, last=last)
            per_frame.append(people)
            # Where each was last seen: this frame's people, and those of before it did not find again.
            last = people + [p for p in last if all(np.linalg.norm(p[0] - q[0]) >= _CROP_KEEP * _side(p)
                                                    for q in people)][:max(0, 2 - len(people))]
            if tick is not None:
                tick()
    finally:
        detector.close()
    return per_frame
