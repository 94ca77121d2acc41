"""Annotations over the preview: camera frusta and paths, agents' trajectories,
behavior layers on the ground, event markers, agent ids.

Lines and ground layers are drawn with OpenGL into the colour target only
(depth-tested against the scene, never into the id or depth buffers); agent
ids are text, drawn with Pillow on the read-back colour.
"""

from __future__ import annotations

import numpy as np

from ...core import model
from . import shaders

# Linear RGBA colours of the annotations.
_FRUSTUM = (1.0, 0.8, 0.05, 1.0)
_EVENT = {"interaction": (1.0, 0.25, 0.6, 1.0), "groupMotion": (0.2, 0.9, 1.0, 1.0),
          "explosion": (1.0, 0.15, 0.0, 1.0), "eruption": (1.0, 0.35, 0.0, 1.0),
          "arrival": (0.3, 1.0, 0.3, 1.0), "dialogue": (0.7, 0.4, 1.0, 1.0)}


def read_events(scene):
    """Every CrowdEvent of the shot (:func:`usdcrowd.scenario.events.read_events`), over its frames."""
    from ...scenario.events import read_events as read

    codes = scene.time_codes
    time = model.TimeRange(float(codes[0]), float(codes[-1]), float(scene.fps))
    rows = {p: i for i, p in enumerate(scene.agent_paths)}
    return read(scene.stage, rows, time, agent_ids=scene._agent_static[1])


def frustum_lines(cam, aspect: float, depth: float = 2.5) -> np.ndarray:
    """(16, 3) endpoints of a camera's frustum pyramid as line segments (world)."""
    hx = 0.5 * cam.horizontal_aperture / cam.focal_length * depth
    hy = hx / aspect
    corners = np.array([[-hx, -hy, -depth], [hx, -hy, -depth], [hx, hy, -depth], [-hx, hy, -depth]])
    apex = np.zeros(3)
    seg = []
    for k in range(4):
        seg += [apex, corners[k], corners[k], corners[(k + 1) % 4]]
    p = np.array(seg)
    return p @ cam.cam_to_world[:3, :3] + cam.cam_to_world[3, :3]


def ring(center: np.ndarray, radius: float, n: int = 32) -> np.ndarray:
    """(2n, 3) segments of a horizontal circle."""
    a = np.linspace(0, 2 * np.pi, n + 1)
    pts = center + radius * np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], 1)
    return np.stack([pts[:-1], pts[1:]], 1).reshape(-1, 3)


def polyline_segments(points: np.ndarray) -> np.ndarray:
    """(t, 3) polyline to (2 (t - 1), 3) segments, skipping non-finite points."""
    ok = np.isfinite(points).all(-1)
    a, b = points[:-1], points[1:]
    keep = ok[:-1] & ok[1:]
    return np.stack([a[keep], b[keep]], 1).reshape(-1, 3)


class Overlays:
    """The chosen annotations of one shot.

    Parameters
    ----------
    scene : ShotScene
    names : iterable of str
        Any of "frusta", "trajectories", "layers", "events", "ids".
    times : array of float, optional
        Time codes the trajectories span (default: the stage's range).
    max_samples : int
        Trajectory samples per agent.
    """

    def __init__(self, scene, names, times=None, max_samples: int = 64):
        self.scene = scene
        self.names = set(names)
        times = np.asarray(scene.time_codes if times is None else times, dtype=np.float64)
        step = max(1, int(np.ceil(len(times) / max_samples)))
        self.sample_times = times[::step] if len(times) else times
        self._static = None       # (segments (k, 3), colours (k, 4)) built on first use
        self._layers = None
        self._gl = None
        self.events = read_events(scene) if "events" in self.names else []

    # ----------------------------------------------------------- geometry
    def static_lines(self) -> tuple[np.ndarray, np.ndarray]:
        """Segments that do not move: trajectories and camera paths (world, linear RGBA)."""
        if self._static is not None:
            return self._static
        segs, cols = [np.zeros((0, 3))], [np.zeros((0, 4))]
        if "trajectories" in self.names and len(self.sample_times) > 1:
            track = np.stack([self.scene.agents(t).keypoints()[:, 4] for t in self.sample_times], 1)  # (n, t, 3)
            poses = self.scene.agents(self.sample_times[0])
            track[..., 2] += 0.03                       # just above the ground it walks on
            for i in np.flatnonzero(poses.visible):
                s = polyline_segments(track[i])
                segs.append(s)
                cols.append(np.tile(np.r_[poses.color[i], 1.0], (len(s), 1)))
        if "frusta" in self.names and len(self.sample_times) > 1:
            for path in self.scene.camera_paths:
                pos = np.array([self.scene.camera(path, t).position for t in self.sample_times])
                s = polyline_segments(pos)
                segs.append(s)
                cols.append(np.tile(_FRUSTUM, (len(s), 1)))
        self._static = (np.concatenate(segs), np.concatenate(cols))
        return self._static

    def dynamic_lines(self, camera, time: float, aspect: float) -> tuple[np.ndarray, np.ndarray]:
        """Segments at ``time``: other cameras' frusta, active events' markers."""
        segs, cols = [np.zeros((0, 3))], [np.zeros((0, 4))]
        if "frusta" in self.names:
            for path in self.scene.camera_paths:
                if path == camera.path:
                    continue
                s = frustum_lines(self.scene.camera(path, time), aspect)
                segs.append(s)
                cols.append(np.tile(_FRUSTUM, (len(s), 1)))
        for ev in self.events:
            i = ev.sample(time)
            if i < 0:
                continue
            c = ev.center[i].copy()
            c[2] = max(c[2], 0.0) + 0.05
            col = _EVENT.get(model.EVENT_KINDS[ev.kind], (1.0, 1.0, 1.0, 1.0))
            s = np.concatenate([ring(c, 1.0), ring(c, 1.15), [c, c + [0, 0, 2.5]]])
            segs.append(s)
            cols.append(np.tile(col, (len(s), 1)))
        return np.concatenate(segs), np.concatenate(cols)

    def layer_quads(self):
        """Behavior layers with painted values: [(corners (4, 3), rgba image (h, w, 4) uint8)]."""
        if self._layers is not None:
            return self._layers
        self._layers = []
        if "layers" not in self.names:
            return self._layers
        from ...scenario import load_scenario

        try:
            fields = load_scenario(self.scene.path, stage=self.scene.stage).fields
        except Exception:    # a shot whose scenario cannot be read still previews, without layers
            fields = []
        palette = np.array([[0.1, 0.3, 0.9], [0.1, 0.8, 0.5], [1.0, 0.8, 0.1], [0.9, 0.2, 0.1]])
        for f in fields:
            if f.values is None:
                continue
            v = np.asarray(f.values, dtype=np.float64)
            span = float(v.max() - v.min()) or 1.0
            t = (v - v.min()) / span
            idx = np.clip(t * (len(palette) - 1), 0, len(palette) - 1 - 1e-9)
            k = idx.astype(int)
            rgb = palette[k] + (palette[k + 1] - palette[k]) * (idx - k)[..., None]
            alpha = 0.15 + 0.4 * t
            img = np.concatenate([rgb, alpha[..., None]], -1)[::-1]      # row 0 is +Y: GL wants it last
            (x0, y0), (x1, y1) = f.extent_min, f.extent_max
            corners = np.array([[x0, y0, 0.015], [x1, y0, 0.015], [x1, y1, 0.015], [x0, y1, 0.015]])
            self._layers.append((corners, np.round(img * 255).astype(np.uint8)))
        return self._layers

    # --------------------------------------------------------------- GL
    def _ensure_gl(self, ctx):
        if self._gl is not None and self._gl["ctx"] is ctx:
            return self._gl
        prog = ctx.program(vertex_shader=shaders.OVERLAY_VS, fragment_shader=shaders.OVERLAY_FS)
        layers = []
        for corners, img in self.layer_quads():
            tex = ctx.texture((img.shape[1], img.shape[0]), 4, np.ascontiguousarray(img).tobytes())
            uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
            quad = np.concatenate([corners, np.ones((4, 4)), uv], 1)[[0, 1, 2, 0, 2, 3]].astype(np.float32)
            vbo = ctx.buffer(quad.tobytes())
            layers.append((ctx.vertex_array(prog, [(vbo, "3f 4f 2f", "in_pos", "in_color", "in_uv")],
                                            skip_errors=True), tex))
        self._gl = {"ctx": ctx, "prog": prog, "layers": layers, "static": None}
        segs, cols = self.static_lines()
        if len(segs):
            data = np.concatenate([segs, cols, np.zeros((len(segs), 2))], 1).astype(np.float32)
            vbo = ctx.buffer(data.tobytes())
            self._gl["static"] = (ctx.vertex_array(prog, [(vbo, "3f 4f 2f", "in_pos", "in_color", "in_uv")],
                                                   skip_errors=True), len(segs))
        return self._gl

    def draw_gl(self, renderer, camera, view, proj, time: float) -> None:
        """Draw lines and layers into the bound (colour-only) framebuffer."""
        import moderngl

        ctx = renderer.ctx
        gl = self._ensure_gl(ctx)
        prog = gl["prog"]
        prog["u_view"].write(np.ascontiguousarray(view, np.float32).tobytes())
        prog["u_proj"].write(np.ascontiguousarray(proj, np.float32).tobytes())
        ctx.enable(moderngl.BLEND | moderngl.DEPTH_TEST)
        ctx.blend_func = moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA
        if gl["layers"]:
            prog["u_has_tex"].value = True
            for vao, tex in gl["layers"]:
                tex.use(2)
                prog["u_tex"].value = 2
                vao.render(moderngl.TRIANGLES)
        if "u_has_tex" in prog:
            prog["u_has_tex"].value = False
        if gl["static"] is not None:
            gl["static"][0].render(moderngl.LINES)
        segs, cols = self.dynamic_lines(camera, time, renderer.width / renderer.height)
        if len(segs):
            data = np.concatenate([segs, cols, np.zeros((len(segs), 2))], 1).astype(np.float32)
            vbo = ctx.buffer(data.tobytes())
            vao = ctx.vertex_array(prog, [(vbo, "3f 4f 2f", "in_pos", "in_color", "in_uv")], skip_errors=True)
            # Markers show through walls: they point at something to look at.
            ctx.disable(moderngl.DEPTH_TEST)
            vao.render(moderngl.LINES)
            vao.release()
            vbo.release()
        ctx.disable(moderngl.BLEND)
        ctx.enable(moderngl.DEPTH_TEST)

    # -------------------------------------------------------------- text
    def annotate(self, color: np.ndarray, renderer, poses, camera, time: float) -> np.ndarray:
        """Agent ids as text above the heads that show in the frame."""
        if "ids" not in self.names or len(poses) == 0:
            return color
        from PIL import Image, ImageDraw

        w, h = renderer.width, renderer.height
        top = poses.keypoints()[:, 3] + np.array([0.0, 0.0, 0.25])
        uv, z = camera.project(top, w, h)
        img = Image.fromarray(np.ascontiguousarray(color))
        draw = ImageDraw.Draw(img)
        shown = set(np.unique(renderer.last_ids).tolist()) if getattr(renderer, "last_ids", None) is not None else None
        for i in np.flatnonzero(poses.visible & (z > 0)):
            aid = int(poses.agent_ids[i])
            if shown is not None and aid not in shown:
                continue
            x, y = uv[i]
            if not (0 <= x < w and 0 <= y < h):
                continue
            text = str(aid)
            draw.text((x - 3 * len(text) + 1, y - 11), text, fill=(0, 0, 0))
            draw.text((x - 3 * len(text), y - 12), text, fill=(255, 255, 255))
        return np.asarray(img)
