"""One sequence of a dataset, from its plan to a filmed shot: scenario, time of day, simulation, cameras.

Everything a plan drew is written into the sequence's scenario stage
(customLayerData ``usdcrowd.dataset``) and its ``plan.json``; the stage alone
re-makes the shot (``usdcrowd simulate scenario.usda``), as its seed, lights
and palette are in it.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import guard
from ..atomic import atomic_path
from ..core.errors import UsdcrowdError

PLAN = "plan.json"
# Static cameras aim here above the crowd's centre (metres): chest height.
AIM_HEIGHT = 1.2
# How far outside the crowd's footprint a static camera may stand (metres):
# further out, walls of the scenery would come between it and the people.
CAMERA_MARGIN = 2.0
APERTURE_MM = 36.0
# Local crowd density: people within DENSITY_RADIUS metres of each person (themselves
# included) per square metre, histogrammed over DENSITY_FRAMES frames of the shot.
DENSITY_RADIUS = 2.0
DENSITY_FRAMES = 5
DENSITY_BINS = np.linspace(0.0, 4.0, 21)


@dataclass
class PreparedSequence:
    """A simulated, filmed sequence, ready to render.

    Attributes
    ----------
    name : str
    split : str
    shot : str
        Its shot.usda.
    cameras : list of (prim path, kind) pairs
        Kinds: "steering", "static", "toric", "overview".
    frames : list of float
        Time codes rendered for every camera.
    notes : list of str
        What the plan asked for and could not be made (a toric camera with no pair in view).
    agents : int
        Agents in the shot.
    density : list of int
        People counted in each DENSITY_BINS bin of local density (:func:`local_density`).
    """

    name: str
    split: str
    shot: str
    cameras: list
    frames: list
    notes: list
    agents: int = 0
    density: list | None = None

    def to_json(self) -> dict:
        return {"name": self.name, "split": self.split, "shot": self.shot, "cameras": self.cameras,
                "frames": self.frames, "notes": self.notes, "agents": self.agents, "density": self.density}


def density_frames(times) -> np.ndarray:
    """The DENSITY_FRAMES time codes, spread over ``times``, at which density is counted."""
    times = np.asarray(times)
    return times[np.unique(np.linspace(0, len(times) - 1, DENSITY_FRAMES).round().astype(int))]


def densities(scene, time: float) -> np.ndarray:
    """(n,) local density of each visible person at ``time``, people per square metre.

    The people within DENSITY_RADIUS metres on the ground (the person
    included) over the disc's area.
    """
    from scipy.spatial import cKDTree

    poses = scene.agents(float(time))
    ground = poses.joints_world[poses.visible, 0, 3, :2]
    if not len(ground):
        return np.zeros(0)
    near = np.array([len(n) for n in cKDTree(ground).query_ball_point(ground, DENSITY_RADIUS)])
    return near / (np.pi * DENSITY_RADIUS ** 2)


def local_density(scene, times) -> list[int]:
    """Histogram (DENSITY_BINS, the last bin open-ended) of :func:`densities` at :func:`density_frames`."""
    counts = np.zeros(len(DENSITY_BINS) - 1, np.int64)
    for t in density_frames(times):
        counts += np.histogram(np.minimum(densities(scene, t), DENSITY_BINS[-1] - 1e-9), DENSITY_BINS)[0]
    return counts.tolist()


def sun_transform(elevation_deg: float, azimuth_deg: float) -> np.ndarray:
    """(4, 4) row-vector world transform of a DistantLight whose light comes from that direction.

    A DistantLight shines along its -Z axis, so its +Z points at the sun:
    (cos e cos a, cos e sin a, sin e) in canonical Z-up metres; its X axis is kept horizontal.
    """
    e, a = np.radians(elevation_deg), np.radians(azimuth_deg)
    z = np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
    x = np.cross([0.0, 0.0, 1.0], z)
    x = x / np.linalg.norm(x) if np.linalg.norm(x) > 1e-9 else np.array([1.0, 0.0, 0.0])
    y = np.cross(z, x)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = x, y, z
    return m


def write_scenario(plan: dict, spec, out_dir: Path) -> str:
    """The plan's scenario stage: a template (and scenery) resized, reseeded, lit for its time of day."""
    from pxr import Gf, Usd, UsdGeom, UsdLux

    from ..scenario.stageio import stage_frame
    from ..jobs.templates import agent_range, new_scenario

    path = out_dir / "scenario.usda"
    scenery = spec.scenery_path(plan["scenery"]) if plan["scenery"] else None
    # The drawn count, within what the template can hold (a fixed cast keeps its size).
    lo, hi = agent_range(plan["template"])
    agents = int(np.clip(plan["agents"], lo, hi if hi is not None else plan["agents"]))
    new_scenario(plan["template"], path, agents, plan["seed"], scenery=scenery)
    stage = Usd.Stage.Open(str(path))
    frame = stage_frame(stage)
    light = plan["light"]
    suns = [p for p in stage.Traverse() if p.IsA(UsdLux.DistantLight)]
    domes = [p for p in stage.Traverse() if p.IsA(UsdLux.DomeLight) or p.GetTypeName() == "DomeLight_1"]
    for prim in suns[:1]:
        sun = UsdLux.DistantLight(prim)
        sun.CreateIntensityAttr(float(light["sun_strength"]))
        sun.CreateNormalizeAttr(True)                 # the strength is the illuminance (UsdLux)
        sun.CreateEnableColorTemperatureAttr(True)
        sun.CreateColorTemperatureAttr(float(light["color_temperature"]))
        world = frame.to_canonical @ sun_transform(light["sun_elevation"], light["sun_azimuth"]) @ frame.from_canonical
        world[:3, 3] = 0.0
        world[3, :3] = 0.0
        world[:3, :3] /= np.linalg.norm(world[:3, :3], axis=1, keepdims=True)
        parent = UsdGeom.Xformable(prim).ComputeParentToWorldTransform(Usd.TimeCode.Default())
        local = Gf.Matrix4d(world.tolist()) * parent.GetInverse()
        xf = UsdGeom.Xformable(prim)
        xf.ClearXformOpOrder()
        xf.AddTransformOp().Set(local)
    for prim in domes[:1]:
        UsdLux.LightAPI(prim).CreateIntensityAttr(float(light["sky_strength"]))
    layer = stage.GetRootLayer()
    data = dict(layer.customLayerData)
    crowd = dict(data.get("usdcrowd", {}))
    crowd["palette"] = plan["palette"]
    crowd["dataset"] = json.dumps(plan, sort_keys=True)
    data["usdcrowd"] = crowd
    layer.customLayerData = data
    from ..atomic import export_layer

    export_layer(layer, path)
    return os.fspath(path)


def _static_track(scene, index: int, cam: dict, times: np.ndarray, aspect: float):
    """A fixed camera looking at the crowd's centre from the plan's azimuth, distance and height."""
    from ..core import model
    from ..core.view import look_at

    t_mid = float(times[len(times) // 2])
    poses = scene.agents(t_mid)
    ground = poses.joints_world[poses.visible, 0, 3, :3] if poses.visible.any() else np.zeros((1, 3))
    centre = ground.mean(0)
    lo, hi = ground[:, :2].min(0) - CAMERA_MARGIN, ground[:, :2].max(0) + CAMERA_MARGIN
    a = np.radians(cam["azimuth"])
    direction = np.array([np.cos(a), np.sin(a)])
    # Walk out along the azimuth no further than the crowd's footprint plus the margin.
    with np.errstate(divide="ignore", invalid="ignore"):
        reach = np.where(direction > 1e-9, (hi - centre[:2]) / direction,
                         np.where(direction < -1e-9, (lo - centre[:2]) / direction, np.inf))
    distance = float(min(cam["distance"], reach.min()))
    eye = np.r_[centre[:2] + distance * direction, centre[2] + cam["height"]]
    target = centre + np.array([0.0, 0.0, AIM_HEIGHT])
    m = np.repeat(look_at(eye, target), len(times), axis=0)
    return model.CameraTrack(f"/World/Cameras/Static_{index}", np.asarray(times, dtype=np.float64), m,
                             np.full(len(times), float(cam["focal_length"])), APERTURE_MM, APERTURE_MM / aspect)


def prepare_sequence(plan: dict, spec, seq_dir: str | os.PathLike) -> PreparedSequence:
    """Make the plan's shot and cameras in ``seq_dir`` (idempotent: a finished sequence is read back).

    Returns
    -------
    PreparedSequence
        Also written to ``seq_dir/plan.json`` with the plan, last (it marks the sequence as prepared).
    """
    from ..cameras.behaviors import Behavior
    from ..jobs.pipeline import simulate_shot
    from ..scenario.shot_scene import ShotScene
    from ..jobs.toric_filming import frame_shot
    from ..scenario.parent_space import ParentSpace
    from ..usd.cameras import add_camera

    seq_dir = Path(seq_dir)
    done = read_prepared(seq_dir, plan)
    if done is not None:
        return done
    guard.make_dir(seq_dir)
    (seq_dir / PLAN).unlink(missing_ok=True)
    scenario = write_scenario(plan, spec, seq_dir)
    last = 1 + (plan["frames"] - 1) * plan["stride"]
    r = simulate_shot(scenario, seq_dir / "shot", seed=plan["seed"], frames=(1, last), progress=False,
                      camera_count=plan["steering"])
    cameras = [(p, "steering") for p in r.camera_paths if "/Agent" in p]
    if plan["overview"]:
        cameras.append((r.camera, "overview"))
    notes = []
    scene = ShotScene(r.shot)
    times = scene.time_codes
    aspect = plan["render"]["resolution"][0] / plan["render"]["resolution"][1]
    for k, cam in enumerate(plan["static"]):
        track = _static_track(scene, k, cam, times, aspect)
        add_camera(r.cameras, track, None, parents=ParentSpace(scene.stage, track.times))
        cameras.append((track.path, "static"))
    if plan["toric"]:
        toric = plan["toric"]
        try:
            _, track, _, _ = frame_shot(r.shot, Behavior(toric["behavior"], toric["shot"]), "auto", smooth=True,
                                        aspect=aspect, progress=False)
            cameras.append((track.path, "toric"))
        except UsdcrowdError as exc:       # no two characters near each other: the other cameras stand
            notes.append(f"no toric camera: {exc}")
    frames = [float(t) for t in np.arange(1, last + 1, plan["stride"], dtype=np.float64)]
    prepared = PreparedSequence(plan["name"], plan["split"], os.fspath(Path(r.shot).resolve()),
                                [list(c) for c in cameras], frames, notes, int(r.n_agents),
                                local_density(scene, times))
    with atomic_path(seq_dir / PLAN) as tmp:
        tmp.write_text(json.dumps({"plan": plan, "prepared": prepared.to_json()}, indent=1, sort_keys=True))
    return prepared


def read_prepared(seq_dir: Path, plan: dict) -> PreparedSequence | None:
    """The sequence made from ``plan`` if ``seq_dir`` holds it whole, else None."""
    try:
        doc = json.loads((Path(seq_dir) / PLAN).read_text())
    except (OSError, ValueError):
        return None
    if doc.get("plan", {}).get("digest") != plan["digest"]:
        return None
    p = doc["prepared"]
    if not Path(p["shot"]).is_file():
        return None
    return PreparedSequence(p["name"], p["split"], p["shot"], [list(c) for c in p["cameras"]], p["frames"],
                            p["notes"], int(p.get("agents", 0)), p.get("density"))
