"""From a scenario stage to a shot: read, simulate, animate, author.

This is the one place that strings the stages of the data flow (docs/architecture.md)
together; the CLI's ``simulate`` and ``demo`` call it.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core import model
from ..core.framestore import FrameStore


PLOT_MAX_AGENTS = 3000


@dataclass
class ShotResult:
    """Where a simulated shot was written and what it holds."""

    shot: str
    crowd: str
    cameras: str
    camera: str
    plot: str
    n_agents: int
    n_frames: int
    seed: int
    camera_paths: list = field(default_factory=list)
    n_events: int = 0


def frame_progress(total: int, desc: str, enabled: bool):
    """A progress bar counting frames (hidden when not ``enabled``)."""
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit="frame", disable=not enabled, leave=False, dynamic_ncols=True)


def simulate_shot(scenario_path: str | os.PathLike, out_dir: str | os.PathLike, seed: int | None = None,
                  frames: tuple[float, float] | None = None, progress: bool = True,
                  chunk_frames: int = 48, camera_count: int | None = None, events: bool = True,
                  limits=None, clip_frames: int | None = None) -> ShotResult:
    """Simulate a scenario and write shot.usda, crowd.usdc and cameras.usda in ``out_dir``.

    Parameters
    ----------
    scenario_path : path-like
        The scenario stage; it is referred to by the shot, never rewritten.
    out_dir : path-like
        Output folder (created).
    seed : int, optional
        Overrides the seed recorded in the scenario.
    frames : (start, end), optional
        Overrides the stage's time range.
    chunk_frames : int
        Frames simulated and authored at a time. Memory does not grow with
        the shot's length: the crowd layer is saved in time windows (value
        clips) and the positions the cameras need wait in a temporary file.
    camera_count : int, optional
        Camera agents to run: the scenario's first N and generated ones
        beyond. Default: the ones the scenario authors.
    events : bool
        Detect events (False: only the authored ones; camera agents then
        scout unless they track those).
    limits : usdcrowd.core.limits.Limits, optional
        Largest agent count, frame count and image accepted (default: the defaults).
    clip_frames : int, optional
        Frames per value-clip window of the crowd layer (default: sized to
        the crowd, see :mod:`usdcrowd.usd.clips`).
    """
    def crowd(scenario):
        from ..sim import SimSettings, simulate_chunks

        return simulate_chunks(scenario, SimSettings(chunk_frames=chunk_frames))

    return author_shot(scenario_path, out_dir, crowd, seed=seed, frames=frames, progress=progress,
                       camera_count=camera_count, events=events, limits=limits, clip_frames=clip_frames)


def author_shot(scenario_path: str | os.PathLike, out_dir: str | os.PathLike,
                crowd_source: Callable[[model.Scenario], Iterable[model.CrowdFrames]],
                seed: int | None = None, frames: tuple[float, float] | None = None,
                progress: bool = True, camera_count: int | None = None, events: bool = True,
                limits=None, clip_frames: int | None = None, label: str = "simulate") -> ShotResult:
    """Read a scenario, take its crowd from ``crowd_source`` and write the shot (``label`` names the
    crowd's progress bar).

    ``crowd_source(scenario)`` yields consecutive :class:`CrowdFrames` chunks
    covering the scenario's time range: the simulation, or any other source
    of trajectories (recorded tracks, tests).
    """
    from pxr import Sdf, UsdLux

    from ..atomic import restored_on_failure
    from ..events import EventDetector
    from ..scenario import stage_frame
    from ..scenario.parent_space import ParentSpace
    from ..usd import CAMERAS, CROWD, CrowdLayerWriter, write_shot
    from ..usd.crowd_layer import write_group_properties
    from ..usd.events import author_events

    scenario_path = os.fspath(scenario_path)
    out_dir = Path(out_dir)
    stage, scenario = _read_scenario(scenario_path, seed, frames, limits)
    sframe = stage_frame(stage)
    default_prim = stage.GetDefaultPrim().GetName() if stage.GetDefaultPrim() else ""
    authored = {p for p in scenario.agents.path if stage.GetPrimAtPath(p)}
    has_lights = any(p.HasAPI(UsdLux.LightAPI) for p in stage.Traverse())
    _claim_shot_folder(out_dir)
    scenario_ref = os.path.relpath(os.path.abspath(scenario_path), out_dir.resolve())

    # Positions for the cameras wait on disk, not in memory (they grow with the shot).
    store = FrameStore(len(scenario.agents), folder=out_dir)
    # Everything generated is authored in its parent's space on the scenario stage.
    space = ParentSpace(stage, scenario.time.codes)
    writer = CrowdLayerWriter(out_dir / CROWD, scenario, sframe, default_prim, scenario_ref, authored,
                              clip_frames=clip_frames, parents=space.table(scenario.agents.path))
    write_group_properties(writer.layer, stage, scenario.groups.path)
    detector = EventDetector(scenario.agents.character_type, scenario.agents.visible, scenario.time.fps,
                             scope=f"/{default_prim}/Events" if default_prim else "/Events")
    collected = _Collected(store)
    # The trajectory map draws at most this many agents at about 200 instants.
    plotted = np.sort(np.random.default_rng(0).permutation(len(scenario.agents))[:PLOT_MAX_AGENTS])
    stride = max(1, scenario.time.n_frames // 200)
    cameras = plot = None
    # A run into an earlier shot's folder replaces its layers one by one: stopped half-way, it puts them back.
    previous = [out_dir / CAMERAS, out_dir / "trajectories.png", out_dir / CROWD, out_dir / "crowd.clips",
                *getattr(writer, "part_paths", [])]
    with restored_on_failure(previous):
        try:
            _author_frames(writer, crowd_source(scenario), scenario, plotted, stride, progress,
                           collected, detector if events else None, label)
            positions = collected.positions
            shot_events = _shot_events(scenario, detector, positions, events)
            with Sdf.ChangeBlock():
                n_events = author_events(writer.layer, shot_events, scenario.agents.path, scenario.agents.agent_id,
                                         sframe, parents=space)
            # The part writers save while the cameras and the picture are made.
            writer.start_saving()
            tracks, cameras = _write_cameras(out_dir, scenario, collected, shot_events, default_prim, sframe,
                                             space, progress, camera_count)
            plot = _plot_trajectories(out_dir, scenario_path, scenario, plotted, collected)
            crowd = writer.save()
        except BaseException:
            writer.abort()          # stop the part writers; nothing half-written is left behind
            raise
        finally:
            store.close()
        # Last: the shot is the entry point, and exists only once everything it sublayers does.
        shot = write_shot(out_dir, scenario_path, scenario.time, sframe, default_prim, scenario.seed,
                          add_lights=not has_lights)
    camera = tracks[0].path
    return ShotResult(shot, crowd, cameras, camera, plot, len(scenario.agents), scenario.time.n_frames,
                      scenario.seed, [t.path for t in tracks], n_events)


def _shot_events(scenario: model.Scenario, detector, positions: FrameStore, events: bool) -> model.EventTable:
    """The scenario's authored events and, when ``events``, those detected in the crowd and its fields."""
    from ..events.scenario import layer_events

    detected = list(detector.finish()) + layer_events(
        scenario.fields, positions, scenario.time.codes, scenario.agents.visible, detector.scope) if events else []
    return model.EventTable(list(scenario.events) + detected)


def _write_cameras(out_dir: Path, scenario: model.Scenario, collected: _Collected, shot_events: model.EventTable,
                   default_prim: str, sframe, space, progress: bool, camera_count: int | None):
    """The shot's camera tracks, filmed and written to the cameras layer: (tracks, the layer's path)."""
    from ..usd.cameras import write_camera_tracks

    tracks = film_cameras(scenario, collected.positions, shot_events, default_prim, progress, count=camera_count,
                          summary=collected.summary())
    cameras = write_camera_tracks(out_dir, tracks, sframe, default_prim, scenario.time,
                                  defined={p for p in scenario.cameras.path},
                                  extra={"seed": int(scenario.seed), "events": len(shot_events)},
                                  parents=space, keep_toric=True)
    return tracks, cameras


def _plot_trajectories(out_dir: Path, scenario_path: str, scenario: model.Scenario, plotted: np.ndarray,
                       collected: _Collected) -> str:
    """trajectories.png: the sampled tracks of the ``plotted`` agents, titled with the shot's size and seed."""
    from .plots import trajectory_map

    return trajectory_map(_subset(scenario, plotted), np.concatenate(collected.tracks),
                          out_dir / "trajectories.png",
                          title=f"{Path(scenario_path).name}: {len(scenario.agents)} agents, "
                                f"{scenario.time.n_frames} frames, seed {scenario.seed}")


def _read_scenario(scenario_path: str, seed, frames, limits):
    """The scenario stage and its model, refused when `validate` reports an error, over ``frames``."""
    from ..core.errors import ScenarioError
    from ..core.limits import DEFAULT
    from ..scenario import load_scenario, open_stage
    from ..scenario.events import read_events
    from .validation import refuse_errors

    stage = open_stage(scenario_path)
    limits = limits or DEFAULT
    scenario = load_scenario(scenario_path, seed=seed, stage=stage, limits=limits)
    refuse_errors(stage, scenario_path)          # and whatever else `usdcrowd validate` reports as an error
    if frames is not None:
        scenario.time = model.TimeRange(float(frames[0]), float(frames[1]), scenario.time.fps)
        if scenario.time.n_frames > limits.max_frames:
            raise ScenarioError(f"{scenario.time.n_frames:,} frames: more than the {limits.max_frames:,} accepted "
                                f"(raise it with --max-frames)", attribute="--frames")
        # The authored events, sampled (and clamped) over the frames simulated.
        scenario.events = read_events(stage, {p: i for i, p in enumerate(scenario.agents.path)}, scenario.time,
                                      agent_ids=scenario.agents.agent_id)
    return stage, scenario


def _claim_shot_folder(out_dir: Path) -> None:
    """The shot folder, checked before any work (not when the shot is finally written): an earlier
    shot's shot.usda is the user's layer, merged; any other layer usdcrowd did not write is refused."""
    from .. import guard
    from ..atomic import output_dir
    from ..usd import CAMERAS, CROWD, SHOT
    from ..usd.shot import earlier_shot

    # Before the folder is claimed: an earlier shot's shot.usda is the user's layer, edited or not; any
    # other file in its place (edited into something else) is refused like any file usdcrowd did not write.
    if earlier_shot(out_dir / SHOT) is not None:
        guard.merge_into(out_dir / SHOT)
    output_dir(out_dir, "shot")
    for name in (SHOT, CROWD, CAMERAS, "trajectories.png", "crowd.clips"):
        guard.check_write(out_dir / name)


@dataclass
class _Collected:
    """What the cameras and the picture need from the simulated chunks."""

    positions: FrameStore
    centres: list = field(default_factory=list)
    spreads: list = field(default_factory=list)
    tracks: list = field(default_factory=list)

    def summary(self) -> tuple[np.ndarray, np.ndarray]:
        from ..cameras.overview import filled

        return filled(np.concatenate(self.centres)), filled(np.concatenate(self.spreads))


def film_cameras(scenario: model.Scenario, positions, events: model.EventTable, default_prim: str,
                 progress: bool, count: int | None = None, static: int = 0,
                 seed: int | None = None, summary: tuple[np.ndarray, np.ndarray] | None = None,
                 static_from: str = "shot") -> list[model.CameraTrack]:
    """The shot's cameras: the overview, the camera agents (the scenario's, or ``count``), static ones.

    Parameters
    ----------
    positions : (t, n, 3) float array or FrameStore
        The crowd over the shot (read a frame at a time).
    count : int, optional
        Number of camera agents: the scenario's first ``count`` and generated
        ones beyond them. Default: the scenario's.
    static : int
        Static cameras at strategic positions (seed 000's baseline).
    static_from : str
        Where the static cameras learn where the crowd goes: ``"shot"``, the
        whole shot (hindsight: seed 000's "strategic positions ... to ensure
        that they would not lose sight of the crowd"), or ``"start"``, its
        first frame only (what anyone knows before the shot).
    summary : ((t, 3), (t,)) float, optional
        The crowd's centroid and spread per frame (:func:`cameras.overview.crowd_summary`),
        when already known.
    """
    from ..cameras import generated_agents, overview_track, static_cameras
    from ..cameras.film import film
    from ..cameras.overview import crowd_summary
    from ..cameras.placement import concat_agents, crowd_extent, take_agents

    root = f"/{default_prim}" if default_prim else ""
    times = scenario.time.codes
    centres, spreads = summary if summary is not None else crowd_summary(positions, scenario.agents.visible)
    tracks = [overview_track(centres, spreads, times, scenario.time.fps, f"{root}/Cameras/CrowdCam")]
    # Placement needs where the crowd goes, not every frame of it.
    sample = positions[:: max(1, len(positions) // 50)]
    agents = scenario.cameras
    if count is not None:
        if count <= len(agents):
            agents = take_agents(agents, np.arange(count))
        else:
            centre, radius = crowd_extent(sample)
            agents = concat_agents(agents, generated_agents(count - len(agents), centre, radius, root,
                                                            start=len(agents) + 1, bounds=scenario.bounds))
    if len(agents):
        rows = {p: i for i, p in enumerate(scenario.agents.path)}
        with frame_progress(len(times), "cameras", progress) as bar:
            tracks += film(positions, times, scenario.time.fps, agents, events, scenario.obstacles, rows,
                           scenario.agents.visible, seed=scenario.seed if seed is None else seed,
                           progress=bar.update, bounds=scenario.bounds, overhead=scenario.overhead)
    if static:
        tracks += static_cameras(sample if static_from == "shot" else positions[:1], static, times, root,
                                 bounds=scenario.bounds, seed=scenario.seed if seed is None else seed)
    return tracks


def _author_frames(writer, chunks, scenario, plotted, stride, progress, collected, detector,
                   label: str = "simulate") -> None:
    """Author (and animate) every chunk; collect what the cameras, the events and the picture need."""
    from ..cameras.overview import crowd_summary

    done = 0
    with frame_progress(scenario.time.n_frames, label, progress) as bar:
        for chunk in chunks:
            writer.write_chunk(chunk)
            if detector is not None:
                detector.feed(chunk)
            position = chunk.position.astype(np.float32)       # as the cameras read it back from a shot
            if chunk.present is not None:                      # NaN where someone is not in the scene
                position[~chunk.present] = np.nan
            collected.positions.append(position)
            centre, spread = crowd_summary(position, scenario.agents.visible, fill=False)
            collected.centres.append(centre)
            collected.spreads.append(spread)
            keep = (done + np.arange(len(chunk.times))) % stride == 0
            collected.tracks.append(position[keep][:, plotted])
            done += len(chunk.times)
            bar.update(len(chunk.times))


def _subset(scenario: model.Scenario, rows: np.ndarray) -> model.Scenario:
    """The scenario with only the given agents (for pictures)."""
    from dataclasses import replace

    a = scenario.agents
    fields = {k: (v[rows] if isinstance(v, np.ndarray) else v if v is None else [v[i] for i in rows])
              for k, v in vars(a).items()}
    return replace(scenario, agents=model.AgentTable(**fields))
