"""Opening stages with clear errors, and their axes and units.

Every stage that comes in is read in its own upAxis and metersPerUnit and
turned into usdcrowd's canonical frame (Z up, metres) with :class:`StageFrame`.
"""

from __future__ import annotations

import contextlib
import os
import sys
from dataclasses import dataclass

import numpy as np

from ..core import model
from ..core.errors import StageError, usd_error_text
from ..core.tolerances import UNIT_RTOL

# A stage without an authored time range is read as this one.
DEFAULT_TIME = model.TimeRange(1.0, 240.0, 24.0)

# Row-vector convention (USD's): p_canonical = p_stage @ matrix.
_Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


@dataclass(frozen=True)
class StageFrame:
    """A stage's up axis and unit, and the maps to and from the canonical frame."""

    up_axis: str = "Z"
    meters_per_unit: float = 1.0

    @property
    def is_canonical(self) -> bool:
        return self.up_axis == "Z" and abs(self.meters_per_unit - 1.0) <= UNIT_RTOL

    @property
    def to_canonical(self) -> np.ndarray:
        """(4, 4) float64: stage coordinates to canonical (row vectors)."""
        m = np.eye(4)
        rot = _Y_UP_TO_Z_UP if self.up_axis == "Y" else np.eye(3)
        m[:3, :3] = rot * self.meters_per_unit
        return m

    @property
    def from_canonical(self) -> np.ndarray:
        """(4, 4) float64: canonical coordinates to stage (row vectors)."""
        return np.linalg.inv(self.to_canonical)

    def points_to_canonical(self, p: np.ndarray) -> np.ndarray:
        """(..., 3) stage points to canonical metres."""
        return np.asarray(p, dtype=np.float64) @ self.to_canonical[:3, :3]

    def points_from_canonical(self, p: np.ndarray) -> np.ndarray:
        """(..., 3) canonical metres to stage points."""
        return np.asarray(p, dtype=np.float64) @ self.from_canonical[:3, :3]

    def length_to_canonical(self, d):
        return np.asarray(d, dtype=np.float64) * self.meters_per_unit


# metersPerUnit accepted: a micrometre to a kilometre per unit (USD's own
# constants span centimetres to kilometres).
METERS_PER_UNIT_RANGE = (1e-6, 1e3)
# timeCodesPerSecond accepted: a frame a second (time codes in seconds) to
# high-speed footage.
FPS_RANGE = (1.0, 1000.0)


def stage_frame(stage) -> StageFrame:
    """Read upAxis and metersPerUnit of an open stage.

    Raises
    ------
    StageError
        An up axis other than Y or Z (the only ones USD defines), or a
        metersPerUnit that is not a number in :data:`METERS_PER_UNIT_RANGE`.
    """
    from pxr import UsdGeom

    up, mpu = str(UsdGeom.GetStageUpAxis(stage)), float(UsdGeom.GetStageMetersPerUnit(stage))
    source = stage.GetRootLayer().identifier
    if up not in ("Y", "Z"):
        raise StageError(f"{up!r} is not an up axis: USD's are \"Y\" and \"Z\"", file=source, attribute="upAxis")
    low, high = METERS_PER_UNIT_RANGE
    if not low <= mpu <= high:          # NaN fails too
        raise StageError(f"{mpu:g} is not a unit: metersPerUnit must be {low:g} (a micrometre) to {high:g} "
                         f"(a kilometre)", file=source, attribute="metersPerUnit")
    return StageFrame(up, mpu)


def time_range(stage) -> model.TimeRange:
    """The stage's frames and rate (:data:`DEFAULT_TIME` when it authors no time range).

    Raises
    ------
    StageError
        Time codes that are not finite or end before they start, or a
        timeCodesPerSecond outside :data:`FPS_RANGE` (0 included: USD would read it as 24).
    """
    fps = float(stage.GetTimeCodesPerSecond())
    source = stage.GetRootLayer().identifier
    if not FPS_RANGE[0] <= fps <= FPS_RANGE[1]:        # NaN fails too
        raise StageError(f"timeCodesPerSecond must be {FPS_RANGE[0]:g} to {FPS_RANGE[1]:g}, got {fps:g}",
                         file=source, attribute="timeCodesPerSecond")
    if stage.HasAuthoredTimeCodeRange():
        start, end = float(stage.GetStartTimeCode()), float(stage.GetEndTimeCode())
    else:
        found = _sublayer_time_range(stage, fps)
        if found is None:
            return DEFAULT_TIME
        start, end = found
    if not (np.isfinite(start) and np.isfinite(end)) or end < start:
        raise StageError(f"endTimeCode {end:g} is before startTimeCode {start:g}" if end < start else
                         f"time codes must be finite, got {start:g} to {end:g}", file=source,
                         attribute="endTimeCode")
    return model.TimeRange(start, end, fps)


def _sublayer_time_range(stage, fps: float) -> tuple[float, float] | None:
    """The time range of the strongest sublayer that has one, when the root layer has none: a layer a
    DCC tool or a layout artist puts over a shot (moving it, editing it) rarely repeats the shot's frames.
    Only a sublayer at the stage's rate and without an offset, whose time codes mean the same frames."""
    for layer in stage.GetLayerStack(includeSessionLayers=False)[1:]:
        if not (layer.HasStartTimeCode() and layer.HasEndTimeCode()):
            continue
        same_rate = not layer.HasTimeCodesPerSecond() or float(layer.timeCodesPerSecond) == fps
        offsets = [o for o in _sublayer_offsets(stage.GetRootLayer(), layer) if not o.IsIdentity()]
        return (float(layer.startTimeCode), float(layer.endTimeCode)) if same_rate and not offsets else None
    return None


def _sublayer_offsets(root, layer) -> list:
    """The layer offsets under which ``root`` sublayers ``layer`` directly (empty when nested deeper)."""
    return [off for path, off in zip(root.subLayerPaths, root.subLayerOffsets)
            if root.ComputeAbsolutePath(path) == layer.identifier or path == layer.identifier]


def open_stage(path: str | os.PathLike):
    """Open a USD stage, turning every way it can fail into one-line errors.

    Every layer the stage is composed from (sublayers, references and
    payloads, followed down) is checked before USD opens it: it must exist
    and be a regular file. A FIFO or a device would make USD block forever;
    a missing layer would only be a warning, and a shot without its crowd
    layer would render nothing.

    Raises
    ------
    StageError
        Missing file, not a regular file, not a USD file, a file USD cannot
        parse, or a layer it needs that is missing or unreadable.
    """
    from pxr import Usd

    path = os.fspath(path)
    _check_layers(path)
    with _captured_stderr() as captured:
        stage = _opened(Usd.Stage.Open, path)
    errors = stage.GetCompositionErrors()
    if errors:
        # A reference to a prim that is not there, a cycle...: USD only warns, and the
        # command would go on with part of the scene missing.
        more = f" (and {len(errors) - 1} more)" if len(errors) > 1 else ""
        raise StageError(f"cannot be composed: {errors[0]}{more}", file=path)
    if captured.text:
        sys.stderr.write(captured.text)        # other warnings still reach the user
    return stage


class _Captured:
    text = ""


@contextlib.contextmanager
def _captured_stderr():
    """Hold what USD's C++ side writes to stderr while a stage opens (its composition
    warnings, which are turned into one-line errors) so it can be replayed or dropped."""
    import tempfile

    captured = _Captured()
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):         # no real stderr (embedded): nothing to hold
        yield captured
        return
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            yield captured
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            captured.text = tmp.read().decode("utf-8", "replace")


def _opened(open_fn, path: str):
    """``open_fn(path)`` (a stage or a layer); USD's failures become one-line StageErrors."""
    from pxr import Tf

    try:
        opened = open_fn(path)
    except Tf.ErrorException as exc:
        raise StageError(f"not a readable USD file: {usd_error_text(exc)}", file=path) from None
    if opened is None:
        raise StageError("not a readable USD file", file=path)
    return opened


def _check_file(path: str, referrer: str | None = None) -> None:
    """A layer file must exist and be a regular file (one-line errors that name who refers to it)."""
    import stat

    where = {"file": referrer} if referrer else {"file": path}
    what = f"refers to {path}, which " if referrer else ""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        raise StageError(f"{what}does not exist" if referrer else "no such file", **where) from None
    except OSError as exc:
        raise StageError(f"{what}cannot be read: {exc.strerror}", **where) from None
    if stat.S_ISDIR(mode):
        raise StageError(f"{what}is a folder, not a USD file", **where)
    if not stat.S_ISREG(mode):
        raise StageError(f"{what}is not a regular file (a pipe or a device)", **where)
    if not os.access(path, os.R_OK):
        raise StageError(f"{what}cannot be read: permission denied", **where)


def _check_layers(root: str) -> None:
    """Check the root layer and every layer it composes, depth first, each once."""
    from pxr import Sdf

    _check_file(root)
    seen, todo = set(), [os.path.abspath(root)]
    while todo:
        path = todo.pop()
        if path in seen:
            continue
        seen.add(path)
        layer = _opened(Sdf.Layer.FindOrOpen, path)
        for asset in layer.GetCompositionAssetDependencies():
            target = _local_asset(layer, asset)
            if target:
                _check_file(_package_file(target), referrer=path)
                todo.append(target)
        for asset in _clip_assets(layer):
            # Value clips open lazily, in the middle of a render: checked now,
            # not followed (a clip only holds samples).
            target = _local_asset(layer, asset)
            if target:
                _check_file(_package_file(target), referrer=path)
                _check_crate(_package_file(target), referrer=path)


def _package_file(target: str) -> str:
    """The file on disk that holds ``target``: a layer inside a package (``shot.usdz[crowd.usdc]``,
    which Sdf opens as it is) is as readable as the package itself."""
    from pxr import Ar

    return Ar.SplitPackageRelativePathOuter(target)[0] if Ar.IsPackageRelativePath(target) else target


def unpacked(resolved: str) -> str:
    """A path on disk for the resolved asset path ``resolved``: itself, or for a file inside a usdz
    (``shot.usdz[0/map.png]``) a copy taken out of the package, since image readers open paths.

    The copy lives in the temporary folder, named after the package's path, size, time and the
    member (reused by worker processes and later runs; a changed package gets a new copy). A member
    the package does not hold gives ``resolved`` back, which the caller reports as missing.
    """
    import hashlib
    import tempfile

    from pxr import Ar

    if not resolved or not Ar.IsPackageRelativePath(resolved):
        return resolved
    package, member = Ar.SplitPackageRelativePathOuter(resolved)
    try:
        st = os.stat(package)
    except OSError:
        return resolved
    key = hashlib.sha256(f"{os.path.abspath(package)}:{st.st_size}:{st.st_mtime_ns}:{member}".encode()).hexdigest()
    folder = os.path.join(tempfile.gettempdir(), f"usdcrowd-unpacked-{os.getuid()}")
    copy = os.path.join(folder, key[:24] + os.path.splitext(member)[1].lower())
    if not os.path.isfile(copy):
        asset = Ar.GetResolver().OpenAsset(Ar.ResolvedPath(resolved))
        if asset is None:
            return resolved
        os.makedirs(folder, exist_ok=True)
        partial = f"{copy}.{os.getpid()}"
        with open(partial, "wb") as fh:
            fh.write(asset.GetBuffer())
        os.replace(partial, copy)               # whole, even beside another process doing the same
    return copy


def _check_crate(path: str, referrer: str) -> None:
    """A usdc file cut short (its table of contents lies past its end), found from its 24-byte header."""
    try:
        with open(path, "rb") as f:
            head = f.read(24)
            size = os.fstat(f.fileno()).st_size
    except OSError as exc:
        raise StageError(f"refers to {path}, which cannot be read: {exc.strerror}", file=referrer) from None
    if head[:8] == b"PXR-USDC" and not 88 <= int.from_bytes(head[16:24], "little") < size:
        raise StageError(f"refers to {path}, which is truncated or damaged (a USD crate file whose table "
                         f"of contents lies past its end)", file=referrer)


def _local_asset(layer, asset: str) -> str | None:
    """The absolute file an asset path of ``layer`` names; None for what only the resolver can tell."""
    # Same-layer references (empty), resolver URIs and expressions are the resolver's business.
    if not asset or "://" in asset or "${" in asset or asset.startswith("`"):
        return None
    target = layer.ComputeAbsolutePath(asset)
    return target if os.path.isabs(target) else None


def _clip_assets(layer) -> list[str]:
    """Value-clip layers (and manifests) a layer names: the USD files among its other asset paths.

    (About 45 ms for a layer of 1,000 agents; clips may be anchored on any prim.)
    """
    from pxr import Sdf, UsdUtils

    if not layer.realPath:
        return []
    _, assets, _ = UsdUtils.ExtractExternalReferences(layer.realPath)
    return [a for a in assets if Sdf.FileFormat.FindByExtension(os.path.splitext(a)[1].lstrip(".") or "-")]


# ------------------------------------------------------------------ units of the layer that authored a value
def correction(source: StageFrame, target: StageFrame) -> np.ndarray:
    """(4, 4) row-vector matrix taking ``source`` stage coordinates into ``target`` ones."""
    return source.to_canonical @ target.from_canonical


def layer_frame(layer) -> StageFrame:
    """Up axis and units a layer declares (USD's fallbacks, Y and centimetres, where it declares none)."""
    from pxr import UsdGeom

    info = layer.pseudoRoot
    up = str(info.GetInfo("upAxis")) if info.HasInfo("upAxis") else str(UsdGeom.GetFallbackUpAxis())
    mpu = float(info.GetInfo("metersPerUnit")) if info.HasInfo("metersPerUnit") else 0.01
    return StageFrame(up, mpu)


def authoring_meters_per_unit(attr, time, stage_frame: StageFrame) -> float:
    """metersPerUnit of the layer that holds ``attr``'s strongest value (the stage's if it declares none).

    Lens and clipping values are in scene units of the file that wrote them:
    a camera referenced from a centimetre DCC file into a metre stage keeps
    its centimetres.
    """
    from pxr import Usd

    t = time if isinstance(time, Usd.TimeCode) else Usd.TimeCode(time)
    for spec in attr.GetPropertyStack(t):
        if spec.HasDefaultValue() or spec.layer.GetNumTimeSamplesForPath(spec.path):
            if spec.layer.pseudoRoot.HasInfo("metersPerUnit"):
                return float(spec.layer.pseudoRoot.GetInfo("metersPerUnit"))
            break
    return stage_frame.meters_per_unit


def lens_scale(attr, time, stage_frame: StageFrame, meters_per_unit: float) -> float:
    """The factor that turns ``attr``'s lens value (authored in its own layer's units) into one read in a
    stage of ``meters_per_unit``: 1 when the units agree (within :data:`~usdcrowd.core.tolerances.UNIT_RTOL`).

    USD does not convert a lens across a reference, so the one factor serves both to warn about a
    mismatch (``validate``) and to author the converted value (``place``).
    """
    from ..core.tolerances import UNIT_RTOL

    ratio = authoring_meters_per_unit(attr, time, stage_frame) / meters_per_unit
    return 1.0 if abs(ratio - 1.0) <= UNIT_RTOL else ratio


def lens_mm(attr, time, stage_frame: StageFrame) -> float | None:
    """A UsdGeom.Camera lens value in millimetres (USD: tenths of the authoring layer's scene unit)."""
    from ..core.view import mm_per_lens_unit

    value = attr.Get(time)
    if value is None:
        return None
    return float(value) * mm_per_lens_unit(authoring_meters_per_unit(attr, time, stage_frame))


def camera_lens(cam, time, stage_frame: StageFrame) -> tuple[float, float, float, float, float]:
    """A UsdGeom.Camera's (focal, horizontal, vertical aperture) in millimetres and (near, far) in metres.

    Each value in the units of the layer that authored it (:func:`lens_mm`,
    :func:`authoring_meters_per_unit`): what the renderers, the camera-agent
    reader and ``inspect`` all use.
    """
    clip = cam.GetClippingRangeAttr()
    near, far = (float(v) * authoring_meters_per_unit(clip, time, stage_frame) for v in clip.Get(time))
    focal, h_ap, v_ap = (lens_mm(a, time, stage_frame) for a in (
        cam.GetFocalLengthAttr(), cam.GetHorizontalApertureAttr(), cam.GetVerticalApertureAttr()))
    return focal, h_ap, v_ap, near, far


def camera_frame(local_to_world: np.ndarray, frame: StageFrame) -> np.ndarray:
    """(4, 4) camera-to-world in canonical metres, rows of unit length, from a camera prim's
    local-to-world ((4, 4), stage units): lenses do not scale with units or a parent's scale.
    Not finite values stay as they are, for the caller to report."""
    m = np.asarray(local_to_world, dtype=np.float64) @ frame.to_canonical
    with np.errstate(invalid="ignore", divide="ignore"):
        m[:3, :3] /= np.linalg.norm(m[:3, :3], axis=1, keepdims=True)
    return m
