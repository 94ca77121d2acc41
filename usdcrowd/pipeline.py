"""From a scenario stage to a shot: read, simulate, animate, author.

This is the one place that strings the stages of DESIGN.md's data flow
together; the CLI's ``simulate`` and ``demo`` call it.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import model


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


def _progress(total: int, desc: str, enabled: bool):
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit="frame", disable=not enabled, leave=False, dynamic_ncols=True)


def simulate_shot(scenario_path: str | os.PathLike, out_dir: str | os.PathLike, seed: int | None = None,
                  frames: tuple[float, float] | None = None, progress: bool = True,
                  chunk_frames: int = 48) -> ShotResult:
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
        Frames simulated and authored at a time (memory stays linear in it).
    """
    def crowd(scenario):
        from .sim import SimSettings, simulate_chunks

        return simulate_chunks(scenario, SimSettings(chunk_frames=chunk_frames))

    return author_shot(scenario_path, out_dir, crowd, seed=seed, frames=frames, progress=progress)


def author_shot(scenario_path: str | os.PathLike, out_dir: str | os.PathLike,
                crowd_source: Callable[[model.Scenario], Iterable[model.CrowdFrames]],
                seed: int | None = None, frames: tuple[float, float] | None = None,
                progress: bool = True) -> ShotResult:
    """Read a scenario, take its crowd from ``crowd_source`` and write the shot.

    ``crowd_source(scenario)`` yields consecutive :class:`CrowdFrames` chunks
    covering the scenario's time range: the simulation, or any other source
    of trajectories (recorded tracks, tests).
    """
    from pxr import UsdLux

    from .plots import trajectory_map
    from .scenario import load_scenario, open_stage, stage_frame
    from .usd import CROWD, CrowdLayerWriter, write_cameras, write_shot
    from .usd.shot import CROWD_CAMERA

    scenario_path = os.fspath(scenario_path)
    out_dir = Path(out_dir)
    stage = open_stage(scenario_path)
    scenario = load_scenario(scenario_path, seed=seed, stage=stage)
    if frames is not None:
        scenario.time = model.TimeRange(float(frames[0]), float(frames[1]), scenario.time.fps)
    sframe = stage_frame(stage)
    default_prim = stage.GetDefaultPrim().GetName() if stage.GetDefaultPrim() else ""
    authored = {p for p in scenario.agents.path if stage.GetPrimAtPath(p)}
    has_lights = any(p.HasAPI(UsdLux.LightAPI) for p in stage.Traverse())
    out_dir.mkdir(parents=True, exist_ok=True)
    scenario_ref = os.path.relpath(os.path.abspath(scenario_path), out_dir.resolve())

    writer = CrowdLayerWriter(out_dir / CROWD, scenario, sframe, default_prim, scenario_ref, authored)
    visible = scenario.agents.visible
    if not visible.any():
        visible = np.ones_like(visible)
    centres, spreads, tracks = [], [], []
    # The trajectory map draws at most this many agents at about 200 instants.
    plotted = np.sort(np.random.default_rng(0).permutation(len(scenario.agents))[:PLOT_MAX_AGENTS])
    stride = max(1, scenario.time.n_frames // 200)
    cameras = plot = None
    try:
        _author_frames(writer, crowd_source(scenario), scenario, visible, plotted, stride, progress,
                       centres, spreads, tracks)
        # The part writers save while the cameras and the picture are made.
        writer.start_saving()
        cameras = write_cameras(out_dir, np.concatenate(centres), np.concatenate(spreads), scenario.time.codes,
                                sframe, default_prim, scenario.time)
        plot = trajectory_map(_subset(scenario, plotted), np.concatenate(tracks), out_dir / "trajectories.png",
                              title=f"{Path(scenario_path).name}: {len(scenario.agents)} agents, "
                                    f"{scenario.time.n_frames} frames, seed {scenario.seed}")
        crowd = writer.save()
    except BaseException:
        writer.abort()          # stop the part writers; nothing half-written is left behind
        for done in (cameras, plot):
            if done is not None and os.path.exists(done):
                os.unlink(done)
        raise
    # Last: the shot is the entry point, and exists only once everything it sublayers does.
    shot = write_shot(out_dir, scenario_path, scenario.time, sframe, default_prim, scenario.seed,
                      add_lights=not has_lights)
    camera = f"/{default_prim}/{CROWD_CAMERA}" if default_prim else f"/{CROWD_CAMERA}"
    return ShotResult(shot, crowd, cameras, camera, plot, len(scenario.agents), scenario.time.n_frames, scenario.seed)


def _author_frames(writer, chunks, scenario, visible, plotted, stride, progress, centres, spreads, tracks) -> None:
    """Author (and animate) every chunk; collect what the camera and the picture need."""
    done = 0
    with _progress(scenario.time.n_frames, "simulate", progress) as bar:
        for chunk in chunks:
            writer.write_chunk(chunk)
            pos = chunk.position[:, visible].astype(np.float64)
            c = pos.mean(axis=1)
            centres.append(c)
            spreads.append(np.linalg.norm(pos - c[:, None], axis=2).max(axis=1))
            keep = (done + np.arange(len(chunk.times))) % stride == 0
            tracks.append(chunk.position[keep][:, plotted])
            done += len(chunk.times)
            bar.update(len(chunk.times))


def _subset(scenario: model.Scenario, rows: np.ndarray) -> model.Scenario:
    """The scenario with only the given agents (for pictures)."""
    from dataclasses import replace

    a = scenario.agents
    fields = {k: (v[rows] if isinstance(v, np.ndarray) else [v[i] for i in rows]) for k, v in vars(a).items()}
    return replace(scenario, agents=model.AgentTable(**fields))
