"""An edited cut as an OpenTimelineIO timeline (``cut.otio``), for editing tools.

One video track; one clip per shot. Each clip's media is the shot stage
(an external reference, relative to the timeline's folder) and its source
range the frames on air, at the shot's frame rate; which camera prim plays
it, the event it is for and why sit in the clip's ``usdcrowd`` metadata.
Editors that read OTIO (OpenTimelineIO's own tools, DaVinci Resolve, Nuke
Studio, Blender's importers) see the cut's shots, their lengths and their
names; a tool that knows USD finds the camera to render each with.
"""

from __future__ import annotations

import os

from ..core.errors import UsdcrowdError

PIP_HINT = "pip install 'usdcrowd[edit]'"


def _otio():
    try:
        import opentimelineio
    except ImportError:
        raise UsdcrowdError(f"writing the cut's timeline needs OpenTimelineIO: {PIP_HINT}") from None
    return opentimelineio


def write_timeline(path: str | os.PathLike, name: str, media: str, fps: float, first: float, last: float,
                   shots: list[dict]) -> str:
    """Write the cut as ``path`` (.otio), atomically.

    Parameters
    ----------
    name : str
        The timeline's name.
    media : str
        The shot stage, relative to ``path``'s folder (or absolute).
    fps : float
    first, last : float
        The shot's first and last time codes (the media's available range).
    shots : list of dict
        In order: ``camera`` (prim path), ``start`` (first time code),
        ``frames``, ``event`` (prim path or ""), ``reason`` (str).
    """
    from ..atomic import atomic_path

    otio = _otio()
    timeline = otio.schema.Timeline(name=name, global_start_time=otio.opentime.RationalTime(first, fps))
    track = otio.schema.Track(name="Cut", kind=otio.schema.TrackKind.Video)
    timeline.tracks.append(track)
    available = otio.opentime.TimeRange(otio.opentime.RationalTime(first, fps),
                                        otio.opentime.RationalTime(last - first + 1, fps))
    for k, shot in enumerate(shots, 1):
        camera = shot["camera"].rsplit("/", 1)[-1]
        event = shot["event"].rsplit("/", 1)[-1] if shot["event"] else ""
        ref = otio.schema.ExternalReference(target_url=media, available_range=available)
        clip = otio.schema.Clip(
            name=f"{k:03d} {camera}" + (f" - {event}" if event else ""), media_reference=ref,
            source_range=otio.opentime.TimeRange(otio.opentime.RationalTime(shot["start"], fps),
                                                 otio.opentime.RationalTime(shot["frames"], fps)))
        clip.metadata["usdcrowd"] = {"camera": shot["camera"], "event": shot["event"], "reason": shot["reason"],
                                     "shot": k}
        track.append(clip)
    with atomic_path(path) as tmp:
        otio.adapters.write_to_file(timeline, os.fspath(tmp), adapter_name="otio_json")
    return os.fspath(path)
