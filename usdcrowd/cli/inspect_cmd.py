"""usdcrowd inspect STAGE [--json] [--agents] | --image PNG [--frame N] [--camera PATH] [--resolution WxH]"""

from __future__ import annotations

import json

import numpy as np

from .args import add_camera, add_force, add_limits, add_resolution, finite_float, limits_of

# The quick look's lens when the stage has no camera: 35 mm on a 36 mm wide film.
QUICK_LOOK_FOCAL, QUICK_LOOK_APERTURE = 35.0, 36.0
# Seen from the front right (azimuth from -Y towards +X) and from above: a three-quarter view.
QUICK_LOOK_AZIMUTH, QUICK_LOOK_ELEVATION = 45.0, 30.0
# Fraction of the half-image the framed box may fill (the rest is a border).
QUICK_LOOK_FILL = 0.9
# Framed when a stage has nothing to draw: 10 x 10 x 2 m about the origin.
EMPTY_BOX = (np.array([-5.0, -5.0, 0.0]), np.array([5.0, 5.0, 2.0]))
DEFAULT_RESOLUTION = (1280, 720)


def add_parser(sub):
    p = sub.add_parser("inspect", help="summarise a stage: layers, groups, agents, layers, cameras, lights",
                       description="Print a readable summary of a scenario or shot stage, or with --agents "
                                   "every agent's name, prim path, id, group, visibility and role, or with "
                                   "--image draw one frame of any stage through the OpenGL preview.")
    p.add_argument("stage", help="a .usda/.usdc/.usd stage")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.add_argument("--agents", action="store_true",
                   help="list every agent instead (one line each: name, path, id, group, visible, role): the "
                        "names --targets, features and --like-targets take")
    p.add_argument("--image", metavar="PNG",
                   help="draw the stage (a scenario, a shot, a DCC file) at --frame into a PNG instead, through "
                        "--camera; on a stage without a camera, a three-quarter view of its bounding box")
    p.add_argument("--frame", type=finite_float(what="a time code"), metavar="N",
                   help="with --image: the time code to draw (default: the stage's start time code)")
    add_camera(p)
    add_resolution(p)
    add_limits(p)
    add_force(p)
    p.set_defaults(run=run, inputs=("stage",), outputs=("image",))


def run(args) -> int:
    from ..jobs.summary import agent_list, format_agents, format_summary, summarize

    _check_options(args)
    if args.image is not None:
        return write_image(args)
    if args.agents:
        agents = agent_list(args.stage, limits=limits_of(args))
        if args.json:           # a JSON array, one agent a line
            print("[" + ",\n ".join(json.dumps(a) for a in agents) + "]")
        else:
            print(format_agents(agents))
        return 0
    s = summarize(args.stage, limits=limits_of(args))
    print(json.dumps(s, indent=2, default=str) if args.json else format_summary(s))
    return 0


def _check_options(args) -> None:
    """The picture's options go with --image, and --image with none of the summary's."""
    from ..core.errors import UsdcrowdError

    if args.image is None:
        named = [name for name, value in (("--frame", args.frame), ("--camera", args.camera),
                                          ("--resolution", args.resolution)) if value is not None]
        if named:
            raise UsdcrowdError(f"{named[0]} goes with --image PNG (the picture's options)")
        return
    if args.agents or args.json:
        raise UsdcrowdError(f"--image draws a picture; {'--agents' if args.agents else '--json'} prints a summary: "
                            f"run them separately")
    if not args.image.lower().endswith(".png"):
        raise UsdcrowdError("--image writes a PNG: name it .png", file=args.image)


def write_image(args) -> int:
    """Draw ``args.stage`` at ``args.frame`` with the OpenGL preview and write the colour as ``args.image``."""
    from ..render.preview import PreviewRenderer
    from ..render.preview.output import write_png
    from ..scenario.shot_scene import ShotScene

    scene = ShotScene(args.stage)
    time = frame_of(scene, args.frame)
    width, height = args.resolution or DEFAULT_RESOLUTION
    camera = camera_of(scene, args.camera, time, width, height)     # a wrong camera fails before any GL work
    renderer = PreviewRenderer(scene, width, height)
    try:
        frame = renderer.render(time, camera)
    finally:
        renderer.release()
    write_png(frame.color, args.image)                   # through a temporary name, renamed when whole
    print(f"wrote {args.image} ({width}x{height}, frame {time:g}, camera {camera.path})")
    return 0


def frame_of(scene, frame: float | None) -> float:
    """The time code to draw: ``frame``, by default the stage's start time code.

    Raises
    ------
    StageError
        ``frame`` outside a time range the stage authors (a typo would draw held values).
    """
    from ..core.errors import StageError

    stage = scene.stage
    time = float(stage.GetStartTimeCode() if frame is None else frame)
    lo, hi = stage.GetStartTimeCode(), stage.GetEndTimeCode()
    if stage.HasAuthoredTimeCodeRange() and not lo - 1e-6 <= time <= hi + 1e-6:
        raise StageError(f"frame {time:g} is outside the stage's frames {lo:g}-{hi:g}", file=scene.path,
                         attribute="--frame")
    return time


def camera_of(scene, path: str | None, time: float, width: int, height: int):
    """The camera at ``path``, else the stage's first, else a three-quarter view of what it draws.

    Returns
    -------
    CameraView
    """
    if path is not None or scene.camera_paths:
        return scene.camera(path, time)
    lo, hi = stage_box(scene, time)
    return three_quarter_view(lo, hi, width, height, time)


def stage_box(scene, time: float) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of what the preview draws at ``time``: scenery meshes and agents' bounding spheres.

    Returns
    -------
    lo, hi : (3,) float64
        Canonical Z-up metres; :data:`EMPTY_BOX` where nothing is drawn.
    """
    from ..render.preview.lod import agent_bounds

    points = []
    for item in scene.scenery:
        world = item.local_to_world(time)
        points.append(item.mesh.vertices.astype(np.float64) @ world[:3, :3] + world[3, :3])
    poses = scene.agents(time)
    if len(poses):
        centres, radius, _ = agent_bounds(poses.joints_world)
        points += [centres - radius[:, None], centres + radius[:, None]]
    if not points:
        return EMPTY_BOX[0].copy(), EMPTY_BOX[1].copy()
    points = np.concatenate(points)
    return points.min(0), points.max(0)


def three_quarter_view(lo, hi, width: int, height: int, time: float = 0.0):
    """A camera that frames the box ``lo``-``hi`` from the front right and above.

    It looks at the box's centre from :data:`QUICK_LOOK_AZIMUTH` and
    :data:`QUICK_LOOK_ELEVATION`, as near as it can while all eight corners
    project inside :data:`QUICK_LOOK_FILL` of the image (the horizontal
    aperture fills the width, pixels are square: :meth:`CameraView.intrinsics`).

    Parameters
    ----------
    lo, hi : (3,) float
        Box corners, canonical Z-up metres.
    width, height : int
        Image size in pixels (the vertical field of view follows the aspect).
    time : float
        Time code the view is stamped with.

    Returns
    -------
    CameraView
    """
    from ..core.view import CameraView, look_at

    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    centre = (lo + hi) / 2.0
    half = np.maximum((hi - lo) / 2.0, 0.25)          # a point or a flat box still has a size to frame
    az, el = np.radians(QUICK_LOOK_AZIMUTH), np.radians(QUICK_LOOK_ELEVATION)
    towards_eye = np.array([np.cos(el) * np.sin(az), -np.cos(el) * np.cos(az), np.sin(el)])
    axes = look_at(centre + towards_eye, centre)[0][:3, :3]       # rows: right, up, back (towards the eye)
    signs = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1], indexing="ij")).reshape(3, -1).T
    local = (signs * half) @ axes.T                                # (8, 3) corners along right, up, back
    tan_x = QUICK_LOOK_FILL * 0.5 * QUICK_LOOK_APERTURE / QUICK_LOOK_FOCAL
    tan_y = tan_x * height / width
    # A corner at (x, y) across and b towards the eye is in frame at distance d when |x| <= tan_x (d - b).
    distance = float(np.max(local[:, 2] + np.maximum(np.abs(local[:, 0]) / tan_x, np.abs(local[:, 1]) / tan_y)))
    depth = distance - local[:, 2]
    cam_to_world = look_at(centre + distance * towards_eye, centre)[0]
    return CameraView("three-quarter view", float(time), cam_to_world, QUICK_LOOK_FOCAL, QUICK_LOOK_APERTURE,
                      QUICK_LOOK_APERTURE * height / width, 0.5 * float(depth.min()), 2.0 * float(depth.max()))
