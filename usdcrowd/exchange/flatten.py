"""A shot as one self-contained USD layer, and as a usdz package of that layer.

``Usd.Stage.Flatten`` composes the layer stack, references and payloads into
one layer, and turns value clips (the crowd.clips/ windows of long shots,
:mod:`usdcrowd.usd.clips`) into ordinary time samples. Asset paths (images of
behavior maps, textures) are made absolute by it; the usdz package carries
those files inside.
"""

from __future__ import annotations

import os

import numpy as np


def flatten_shot(stage, times: np.ndarray | None = None, progress: bool = False):
    """The composed ``stage`` as one anonymous Sdf layer.

    Parameters
    ----------
    stage : Usd.Stage
    times : (t,) float, optional
        Keep time samples at these time codes only (the values the stage has
        there: held, interpolated or from a clip); the layer's time range
        becomes theirs. None keeps every sample.
    progress : bool
        Show a progress bar over the attributes resampled.

    Returns
    -------
    Sdf.Layer
    """
    layer = stage.Flatten()
    if times is not None:
        keep_frames(layer, stage, np.asarray(times, dtype=np.float64), progress)
    _forget_scenario(layer, stage)
    return layer


def sampled_paths(layer) -> list:
    """Paths of the attributes in ``layer`` that hold time samples."""
    from pxr import Sdf

    found = []
    layer.Traverse(Sdf.Path.absoluteRootPath,
                   lambda path: found.append(path) if path.IsPropertyPath()
                   and layer.GetNumTimeSamplesForPath(path) else None)
    return found


def keep_frames(layer, stage, times: np.ndarray, progress: bool = False) -> int:
    """Replace the time samples of ``layer`` by the values ``stage`` gives at ``times``.

    A value that holds between sparse samples (a behavior token) is written
    at each kept time, so nothing the frames showed is lost with the samples
    around them.

    Returns
    -------
    int
        How many attributes were resampled.
    """
    from pxr import Sdf
    from tqdm import tqdm

    from ..scenario.samples import sample_values

    paths = sampled_paths(layer)
    keys = [float(t) for t in times]
    for path in tqdm(paths, desc="export frames", unit="attr", disable=not progress, leave=False):
        values = sample_values(stage.GetAttributeAtPath(path), keys)
        with Sdf.ChangeBlock():
            for t in layer.ListTimeSamplesForPath(path):
                layer.EraseTimeSample(path, t)
            for t, value in zip(keys, values):
                if value is not None:
                    layer.SetTimeSample(path, t, value)
    layer.startTimeCode, layer.endTimeCode = keys[0], keys[-1]
    return len(paths)


def _forget_scenario(layer, stage) -> None:
    """Drop the scenario a shot records (customLayerData usdcrowd:scenario, its files' hashes): the
    flattened layer holds the scenario itself, and moved elsewhere its relative path would name
    another file. Where it came from is kept as ``exportedFrom``."""
    data = dict(layer.customLayerData or {})
    ours = dict(data.get("usdcrowd") or {}) if isinstance(data.get("usdcrowd"), dict) else None
    if ours is None:
        return
    ours.pop("scenario", None)
    ours.pop("scenarioFiles", None)
    ours["exportedFrom"] = stage.GetRootLayer().realPath or stage.GetRootLayer().identifier
    data["usdcrowd"] = ours
    layer.customLayerData = data


def write_usdz(layer, final: str | os.PathLike) -> str:
    """Package ``layer`` (and the files its asset paths name) as the usdz ``final``, whole or not at all.

    The package's root layer is ``<final's stem>.usdc``.
    """
    import errno
    import shutil
    from pathlib import Path

    from pxr import Sdf, UsdUtils

    from ..atomic import atomic_path

    final = os.fspath(final)
    with atomic_path(final) as tmp:
        # Beside the output (same disk), under a temporary name a later run cleans up if this one is killed.
        folder = Path(tmp).with_suffix(".layers")
        try:
            folder.mkdir()
            inner = folder / f"{Path(final).stem}.usdc"
            if not layer.Export(os.fspath(inner)):
                raise OSError(errno.EIO, "USD could not save the flattened layer", final)
            if not UsdUtils.CreateNewUsdzPackage(Sdf.AssetPath(os.fspath(inner)), os.fspath(tmp)):
                raise OSError(errno.EIO, "USD could not write the usdz package", final)
        finally:
            shutil.rmtree(folder, ignore_errors=True)
    return final
