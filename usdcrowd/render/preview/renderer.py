"""PreviewRenderer: a shot drawn with OpenGL, with colour, ids and depth.

Built once per shot (programs, the body's levels of detail, scenery buffers,
the shadow map), then :meth:`PreviewRenderer.render` draws one time code from
one camera and reads back

- ``color`` (h, w, 3) uint8, sRGB-encoded in the fragment shader;
- ``ids`` (h, w) uint32: the agent's track id, 0 for background, scenery
  shape ids (>= SCENERY_ID_BASE) as in :class:`ShotScene`;
- ``depth`` (h, w) float32: z-depth along the view axis in metres (as
  :meth:`CameraView.project` returns it), +inf on background.

Projection follows :meth:`CameraView.intrinsics`: the horizontal aperture
fills the width, square pixels, principal point at the image centre, so a
point projected with :meth:`CameraView.project` lands on the pixel the
rasteriser draws it on. Rows are top to bottom: the projection flips Y, so
the read-back needs no flip.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from ...character.poses import AgentPoses
from ...core.geometry import face_normals, vertex_normals
from ...core.view import CameraView
from ...scenario.shot_scene import ShotScene
from . import impostors, instancing, lod, shaders, shadows
from .context import headless_context


@dataclass
class PreviewFrame:
    """One rendered frame (unpacks as ``color, ids, depth``).

    Attributes
    ----------
    color : (h, w, 3) uint8
    ids : (h, w) uint32
    depth : (h, w) float32
    time : float
    camera : CameraView
    stats : dict
        Counts of drawn characters per level of detail, culled, and so on.
    """

    color: np.ndarray
    ids: np.ndarray
    depth: np.ndarray
    time: float = 0.0
    camera: CameraView | None = None
    stats: dict = field(default_factory=dict)

    def __iter__(self):
        return iter((self.color, self.ids, self.depth))

    def boxes(self) -> dict[int, tuple[int, int, int, int]]:
        """Tight agent boxes from the id buffer; see :func:`boxes_from_ids`."""
        return boxes_from_ids(self.ids)


def boxes_from_ids(ids: np.ndarray, include_scenery: bool = False) -> dict[int, tuple[int, int, int, int]]:
    """Tight pixel boxes of every id in an id buffer.

    Parameters
    ----------
    ids : (h, w) uint32
        Id buffer (0 is background).
    include_scenery : bool
        Also return boxes of scenery ids (>= SCENERY_ID_BASE).

    Returns
    -------
    dict
        ``{agent_id: (x0, y0, x1, y1)}`` in pixels, x1 and y1 exclusive (the
        box covers columns x0 .. x1 - 1), so ``(x1 - x0) * (y1 - y0)`` is its
        area and IoU needs no +1.
    """
    from ...core.shading import SCENERY_ID_BASE

    ids = np.asarray(ids)
    ys, xs = np.nonzero(ids)
    if len(xs) == 0:
        return {}
    vals = ids[ys, xs]
    if not include_scenery:
        keep = vals < SCENERY_ID_BASE
        ys, xs, vals = ys[keep], xs[keep], vals[keep]
    uniq, inv = np.unique(vals, return_inverse=True)
    x0 = np.full(len(uniq), np.iinfo(np.int64).max)
    y0 = x0.copy()
    x1 = np.full(len(uniq), -1)
    y1 = x1.copy()
    np.minimum.at(x0, inv, xs)
    np.minimum.at(y0, inv, ys)
    np.maximum.at(x1, inv, xs)
    np.maximum.at(y1, inv, ys)
    return {int(u): (int(a), int(b), int(c) + 1, int(d) + 1) for u, a, b, c, d in zip(uniq, x0, y0, x1, y1)}


def projection(camera: CameraView, width: int, height: int, flip_y: bool) -> np.ndarray:
    """Row-vector OpenGL projection matching ``camera.intrinsics(width, height)``.

    Returns
    -------
    (4, 4) float64
        ``clip = [x, y, z, 1]_cam @ P``; with ``flip_y`` image row 0 is GL's
        first row in memory, so read-backs are top to bottom.
    """
    f = camera.intrinsics(width, height)[0, 0]
    n, fa = float(camera.near), float(camera.far)
    p = np.zeros((4, 4))
    p[0, 0] = 2.0 * f / width
    p[1, 1] = (-2.0 if flip_y else 2.0) * f / height
    p[2, 2] = -(fa + n) / (fa - n)
    p[3, 2] = -2.0 * fa * n / (fa - n)
    p[2, 3] = -1.0
    return p


@dataclass
class _Lights:
    sun_dir: np.ndarray | None
    sun: np.ndarray
    sky: np.ndarray
    lamp_pos: np.ndarray      # (8, 4)
    lamp_rgb: np.ndarray      # (8, 4)
    lamp_dir: np.ndarray      # (8, 4)
    n_lamps: int


def stage_lights(scene: ShotScene) -> _Lights:
    """The stage's UsdLux lights as the preview's shader sees them.

    The first DistantLight is the sun (its intensity is irradiance, shadowed
    by the shadow map); DomeLights add a uniform sky radiance; sphere, disk,
    rect and cylinder lights become up to 8 unshadowed small lamps. A stage
    with no light at all gets a default sun and sky so it is not black.
    """
    lights = scene.lights
    sun_dir, sun, sky = None, np.zeros(3), np.zeros(3)
    lamps = []
    for light in lights:
        rgb = np.asarray(light.rgb, dtype=np.float64) * light.intensity
        z_axis = light.to_world[2, :3] / np.linalg.norm(light.to_world[2, :3])
        if light.kind == "distant" and sun_dir is None:
            sun_dir, sun = z_axis, rgb / np.pi
        elif light.kind == "distant":
            sky += rgb / np.pi * max(z_axis[2], 0.0) * 0.5   # extra suns: no shadow, a soft fill
        elif light.kind == "dome":
            sky += rgb
        else:
            # Small-source irradiance E = L * A_projected / d^2; normalize
            # divides the radiance by the area, leaving the power factor.
            if light.kind == "sphere":
                area, one_sided = np.pi * light.radius ** 2, False
            elif light.kind == "disk":
                area, one_sided = np.pi * light.radius ** 2, True
            elif light.kind == "rect":
                area, one_sided = light.width * light.height, True
            else:
                area, one_sided = 2.0 * light.radius * light.length, False
            if light.normalize:
                area = 0.25 if light.kind == "sphere" else 1.0
            lamps.append((light.to_world[3, :3], rgb * area, -z_axis, one_sided, float(rgb.sum() * area)))
    if sun_dir is None and not sky.any() and not lamps:
        sun_dir, sun, sky = np.array([0.4, -0.5, 0.77]), np.full(3, 2.5 / np.pi), np.full(3, 0.5)
    lamps.sort(key=lambda row: -row[4])
    lamps = lamps[:8]
    pos, rgb, ldir = np.zeros((8, 4)), np.zeros((8, 4)), np.zeros((8, 4))
    for i, (p, c, d, one_sided, _) in enumerate(lamps):
        pos[i, :3], rgb[i, :3], ldir[i, :3], ldir[i, 3] = p, c, d, float(one_sided)
    if sun_dir is not None:
        sun_dir = sun_dir / np.linalg.norm(sun_dir)
    return _Lights(sun_dir, sun, sky, pos, rgb, ldir, len(lamps))


def _flat_mesh(vertices: np.ndarray, faces: np.ndarray, normals: np.ndarray | None, uv: np.ndarray | None,
               crease_deg: float = 35.0) -> np.ndarray:
    """Triangle soup (3f, 8) float32: position, normal, uv.

    Corners keep the smooth vertex normal unless it leans more than
    ``crease_deg`` from the face normal (cube edges stay sharp, cylinders
    stay round).
    """
    v = np.asarray(vertices, dtype=np.float64)
    fn = face_normals(v, faces)
    vn = normals if normals is not None and len(normals) == len(v) else vertex_normals(v, faces)
    corner_n = np.asarray(vn, dtype=np.float64)[faces]                         # (f, 3, 3)
    corner_n /= np.maximum(np.linalg.norm(corner_n, axis=-1, keepdims=True), 1e-12)
    smooth = np.einsum("fkc,fc->fk", corner_n, fn) > np.cos(np.radians(crease_deg))
    corner_n = np.where(smooth[..., None], corner_n, fn[:, None, :])
    uv_c = np.asarray(uv, dtype=np.float64)[faces] if uv is not None and len(uv) == len(v) else np.zeros(faces.shape + (2,))
    return np.concatenate([v[faces], corner_n, uv_c], -1).reshape(-1, 8).astype(np.float32)


@dataclass
class _SceneryDraw:
    item: object
    vao: object
    shadow_vao: object
    world: np.ndarray         # (4, 4) cached for static items
    texture: object = None


def _set(prog, name: str, value) -> None:
    """Set a uniform if the compiler kept it (unused uniforms are removed)."""
    if name in prog:
        u = prog[name]
        if isinstance(value, np.ndarray):
            u.write(np.ascontiguousarray(value, dtype=np.float32 if value.dtype.kind == "f" else value.dtype).tobytes())
        else:
            u.value = value


class PreviewRenderer:
    """Draws a shot with OpenGL; one instance per shot and image size.

    Parameters
    ----------
    scene : ShotScene or path-like
        The shot.
    width, height : int
        Image size in pixels.
    ctx : moderngl.Context, optional
        A context to draw with (the viewer's window); default: headless EGL.
    lod_settings : LodSettings, optional
        Level of detail and culling; ``LodSettings(enabled=False)`` draws
        every character with its full mesh.
    shadow_size : int
        Texels along the side of the sun's shadow map.
    shadow_distance : float
        Metres from the camera that the shadow map covers.
    exposure : float
        Multiplies linear radiance before the sRGB encoding.
    overlays : Overlays, optional
        Annotations drawn over the colour (not into ids or depth).
    shadows : bool
        Draw the sun's shadow map (characters and scenery cast shadows).

    Raises
    ------
    UsdcrowdError
        If moderngl is missing or no OpenGL context can be made.
    """

    def __init__(self, scene, width: int = 640, height: int = 360, *, ctx=None,
                 lod_settings: lod.LodSettings | None = None, shadow_size: int = 2048,
                 shadow_distance: float = 120.0, exposure: float = 1.0, overlays=None,
                 shadows: bool = True):
        self.scene = scene if isinstance(scene, ShotScene) else ShotScene(os.fspath(scene))
        self.width, self.height = int(width), int(height)
        self.ctx = ctx if ctx is not None else headless_context()
        self.lod = lod_settings or lod.LodSettings()
        self.shadow_size = int(shadow_size)
        self.shadow_distance = float(shadow_distance)
        self.exposure = float(exposure)
        self.overlays = overlays
        self.shadows = bool(shadows)
        self._poses_cache: dict[float, AgentPoses] = {}
        self._build()

    # ----------------------------------------------------------------- setup
    def _build(self) -> None:
        """Everything drawing needs, made once: programs, body and scenery buffers, targets, lights."""
        import moderngl

        ctx = self.ctx
        self._moderngl = moderngl
        self.lights = stage_lights(self.scene)
        self.prog_char = ctx.program(vertex_shader=shaders.CHARACTER_VS, fragment_shader=shaders.CHARACTER_FS)
        self.prog_scenery = ctx.program(vertex_shader=shaders.SCENERY_VS, fragment_shader=shaders.SCENERY_FS)
        self.prog_shadow_char = ctx.program(vertex_shader=shaders.SHADOW_CHARACTER_VS,
                                            fragment_shader=shaders.DEPTH_ONLY_FS)
        self.prog_shadow_scenery = ctx.program(vertex_shader=shaders.SHADOW_SCENERY_VS,
                                               fragment_shader=shaders.DEPTH_ONLY_FS)

        self._build_bodies()
        self._instances = None
        self._instance_capacity = 0
        self._slots = None
        self._slot_capacity = 0
        self._build_impostors()
        self._build_scenery()
        self._build_targets()

        from ...core.srgb import srgb8

        # Background: the sky's colour through the same display transform.
        sky = self.lights.sky * self.exposure if self.lights.sky.any() else np.array([0.5, 0.55, 0.6])
        self.background = srgb8(np.clip(sky, 0, 1) * 0.9)

        for prog in self._lit_programs():
            self._set_lights(prog)

    def _build_bodies(self) -> None:
        """The body's levels of detail and their vertex arrays (and the coarse mesh that casts shadows)."""
        body = self.scene.body
        self.body = instancing.body_lods(body.points, body.faces, body.joint_indices, body.joint_weights,
                                         cells=self.lod.cells, regions=body.regions)
        # Per geometry: (main vao, shadow vao); the point list last.
        self._body_vaos = [self._skinned_vaos(geom, (self.prog_char, self.prog_shadow_char))
                           for geom in (*self.body.meshes, self.body.points)]
        self._shadow_mesh_vao = None
        if self.lod.shadow_cell > 0:
            coarse = instancing.body_lods(body.points, body.faces, body.joint_indices, body.joint_weights,
                                          cells=(self.lod.shadow_cell,), regions=body.regions).meshes[1]
            (self._shadow_mesh_vao,) = self._skinned_vaos(coarse, (self.prog_shadow_char,))

    def _build_impostors(self) -> None:
        """The impostor atlas and its programs, when the level-of-detail settings draw far characters so."""
        ctx = self.ctx
        self.atlas = None
        if self.lod.impostor_min_px is not None:
            full = self.body.meshes[0].vertices
            self.atlas = impostors.build_atlas(ctx, full[:, :3], self.body.meshes[0].indices.reshape(-1, 3),
                                               full[:, 6:9], full[:, 3:6], full[:, 9:])
            self.prog_imp = ctx.program(vertex_shader=shaders.IMPOSTOR_VS, fragment_shader=shaders.IMPOSTOR_FS)
            self.prog_shadow_imp = ctx.program(vertex_shader=shaders.SHADOW_IMPOSTOR_VS,
                                               fragment_shader=shaders.SHADOW_IMPOSTOR_FS)
            self.prog_imp_place = ctx.compute_shader(shaders.IMPOSTOR_CS)
            self._imp_vaos = None         # (view, shadow), made with the quad indices
            self._imp_index = None
            self._imp_capacity = 0        # agents the quad indices cover
            self._sprites = None
            self._sprite_capacity = 0     # bytes
            for prog in (self.prog_imp, self.prog_shadow_imp, self.prog_imp_place):
                for name, value in self.atlas.uniforms().items():
                    _set(prog, name, value)
                _set(prog, "u_atlas", 2)
                _set(prog, "u_cell_box", 3)
            _set(self.prog_imp, "u_regions", 4)

    def _build_scenery(self) -> None:
        """Every scenery item's vertex arrays and texture, posed at the first frame, and the box round them."""
        ctx = self.ctx
        t0 = float(self.scene.time_codes[0]) if len(self.scene.time_codes) else 0.0
        self._scenery = []
        lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
        for item in self.scene.scenery:
            soup = _flat_mesh(item.mesh.vertices, item.mesh.faces, item.mesh.normals, item.mesh.uv)
            vbo = ctx.buffer(soup.tobytes())
            vao = ctx.vertex_array(self.prog_scenery, [(vbo, "3f 3f 2f", "in_pos", "in_nrm", "in_uv")],
                                   skip_errors=True)
            svao = ctx.vertex_array(self.prog_shadow_scenery, [(vbo, "3f 20x", "in_pos")], skip_errors=True)
            world = item.local_to_world(t0)
            tex = self._load_texture(item)
            self._scenery.append(_SceneryDraw(item, vao, svao, world, tex))
            wp = item.mesh.vertices.astype(np.float64) @ world[:3, :3] + world[3, :3]
            lo, hi = np.minimum(lo, wp.min(0)), np.maximum(hi, wp.max(0))
        self._scenery_box = (lo, hi)

    def _build_targets(self) -> None:
        """The framebuffers drawn into: colour, ids and linear depth at the image size, the sun's shadow map."""
        ctx, moderngl = self.ctx, self._moderngl
        w, h = self.width, self.height
        self.color_tex = ctx.texture((w, h), 4, dtype="f1")
        self.id_tex = ctx.texture((w, h), 1, dtype="u4")
        self.depth_lin_tex = ctx.texture((w, h), 1, dtype="f4")
        self.depth_rb = ctx.depth_texture((w, h))
        self.fbo = ctx.framebuffer([self.color_tex, self.id_tex, self.depth_lin_tex], self.depth_rb)
        self.fbo_color = ctx.framebuffer([self.color_tex], self.depth_rb)    # overlays: colour only

        s = self.shadow_size
        self.shadow_tex = ctx.depth_texture((s, s))
        self.shadow_tex.compare_func = "<="
        self.shadow_tex.repeat_x = self.shadow_tex.repeat_y = False
        self.shadow_tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self.shadow_fbo = ctx.framebuffer(depth_attachment=self.shadow_tex)
        self.shadow_fbo.clear(depth=1.0)      # without shadows the map stays empty: all lit

    def _skinned_vaos(self, geom, programs) -> tuple:
        """Vertex arrays of one body geometry (position, normal, joint weights) for each program."""
        ctx = self.ctx
        vbo = ctx.buffer(geom.vertices.tobytes())
        ibo = ctx.buffer(geom.indices.astype(np.int32).tobytes()) if geom.indices is not None else None
        content = [(vbo, "3f 3f 3f 4f 2f", "in_pos", "in_nrm", "in_w", "in_region", "in_region45")]
        return tuple(ctx.vertex_array(prog, content, ibo, 4, skip_errors=True) for prog in programs)

    def _lit_programs(self) -> tuple:
        return (self.prog_scenery, self.prog_char) + ((self.prog_imp,) if self.atlas is not None else ())

    def _load_texture(self, item):
        path = item.material.base_color_texture
        if not path or item.mesh.uv is None or not os.path.exists(path):
            return None
        from PIL import Image

        with Image.open(path) as im:
            img = im.convert("RGBA").transpose(Image.FLIP_TOP_BOTTOM)   # GL's v runs up
        tex = self.ctx.texture(img.size, 4, img.tobytes(), internal_format=0x8C43)  # GL_SRGB8_ALPHA8
        tex.build_mipmaps()
        return tex

    def _set_lights(self, prog) -> None:
        L = self.lights
        _set(prog, "u_sun_dir", np.asarray(L.sun_dir if L.sun_dir is not None else [0, 0, 1], np.float32))
        _set(prog, "u_sun", np.asarray(L.sun if L.sun_dir is not None else np.zeros(3), np.float32))
        _set(prog, "u_sky", L.sky.astype(np.float32))
        _set(prog, "u_n_lamps", L.n_lamps)
        _set(prog, "u_lamp_pos", L.lamp_pos.astype(np.float32))
        _set(prog, "u_lamp_rgb", (L.lamp_rgb / np.pi).astype(np.float32))
        _set(prog, "u_lamp_dir", L.lamp_dir.astype(np.float32))
        _set(prog, "u_exposure", self.exposure)
        _set(prog, "u_shadow", 0)

    # -------------------------------------------------------------- per frame
    def poses(self, time) -> AgentPoses:
        """The agents at ``time`` (the last few are cached)."""
        key = float(time)
        if key not in self._poses_cache:
            if len(self._poses_cache) > 4:
                self._poses_cache.clear()
            self._poses_cache[key] = self.scene.agents(key)
        return self._poses_cache[key]

    def camera(self, camera, time) -> CameraView:
        """A CameraView from a CameraView, a camera prim path or None (the first camera)."""
        return camera if isinstance(camera, CameraView) else self.scene.camera(camera, time)

    def render(self, time, camera=None) -> PreviewFrame:
        """Draw the shot at ``time`` and read back colour, ids and depth.

        Parameters
        ----------
        time : float
            Time code.
        camera : CameraView, str or None
            A camera, a camera prim path, or None for the stage's first camera.

        Returns
        -------
        PreviewFrame
        """
        cam = self.camera(camera, time)
        return self.render_poses(self.poses(time), cam, time)

    def render_poses(self, poses: AgentPoses, camera: CameraView, time=None) -> PreviewFrame:
        """Draw given poses from a given camera and read the frame back."""
        t = float(poses.time if time is None else time)
        stats = self.draw(poses, camera, t)
        color, ids, depth = self.read()
        self.last_ids = ids
        if self.overlays is not None:
            color = self.overlays.annotate(color, self, poses, camera, t)
        return PreviewFrame(color, ids, depth, t, camera, stats)

    def read(self):
        """Read the last frame back: color (h, w, 3) uint8, ids (h, w) uint32, depth (h, w) float32."""
        w, h = self.width, self.height
        color = np.frombuffer(self.fbo.read(components=3, attachment=0), np.uint8).reshape(h, w, 3)
        ids = np.frombuffer(self.fbo.read(components=1, attachment=1, dtype="u4"), np.uint32).reshape(h, w)
        depth = np.frombuffer(self.fbo.read(components=1, attachment=2, dtype="f4"), np.float32).reshape(h, w)
        return color, ids, depth

    def draw(self, poses: AgentPoses, camera: CameraView, time: float, target=None, flip_y: bool = True) -> dict:
        """Draw one frame into the offscreen targets (or ``target``'s colour).

        Parameters
        ----------
        target : moderngl.Framebuffer, optional
            Where the colour goes after drawing (the viewer's screen);
            default: only the offscreen colour, ids and depth.
        flip_y : bool
            Rows top to bottom in memory (for read-back); the window wants
            False.

        Returns
        -------
        dict
            Counts: ``drawn`` per level, ``culled``, ``agents``.
        """
        w, h = self.width, self.height
        view = camera.world_to_cam
        proj = projection(camera, w, h, flip_y)
        focal = float(camera.intrinsics(w, h)[0, 0])
        plan = self._plan(poses, camera, view, focal)
        # One record per agent; draws index them through the slot list.
        n = plan["n"]
        self._upload(instancing.pack_poses(poses.joints_world, poses.palette, poses.agent_ids) if n
                     else np.zeros((0, shaders.INSTANCE_STRIDE, 4), np.float32))
        s_base = len(plan["order"])
        self._upload_slots(np.concatenate([plan["order"], plan["s_order"]]))
        if self.atlas is not None:
            self.atlas.texture.use(2)
            self.atlas.boxes.use(3)
            self.atlas.regions.use(4)
        shadow = self._shadow_pass(plan, camera, view, focal, time, s_base)
        self._view_pass(plan, camera, view, proj, focal, time, shadow, flip_y)
        if self.overlays is not None:
            self.fbo_color.use()
            self.overlays.draw_gl(self, camera, view, proj, time)
        if target is not None:
            self.ctx.copy_framebuffer(target, self.fbo)
        counts = np.diff(plan["starts"])
        m, p = self.lod.n_meshes, self.lod.first_point_level
        return {"agents": n, "culled": int((plan["draw_mask"] & ~plan["in_view"]).sum()),
                "shadow_casters": int(plan["casts"].sum()),
                "full": int(counts[0]), "coarse": int(counts[1:m].sum()), "impostors": int(counts[m:p].sum()),
                "points": int(counts[p:].sum()), "levels": counts.tolist(), "shadow_texels": int(shadow[3])}

    def _plan(self, poses: AgentPoses, camera: CameraView, view, focal: float) -> dict:
        """Which agents are drawn, at which level (nearest first), and which cast shadows."""
        w, h = self.width, self.height
        n = len(poses)
        centres, radius, body_h = lod.agent_bounds(poses.joints_world) if n else (np.zeros((0, 3)),) * 3
        draw_mask = np.asarray(poses.visible, dtype=bool).copy()
        if n and self.lod.cull:
            in_view = lod.in_frustum(centres, radius, view, focal, w, h, camera.near, camera.far)
        else:
            in_view = np.ones(n, dtype=bool)
        pixels = lod.screen_height(centres, body_h, view, focal) if n else np.zeros(0)
        drawn = draw_mask & in_view
        levels = lod.choose_levels(pixels, self.lod, drawn)
        n_levels = self.lod.n_levels
        nearest_first = -pixels / body_h if n else None
        order, starts = lod.group_by_level(levels, drawn, n_levels, distance=nearest_first)

        # Shadow casters: drawn agents plus those just outside the frustum
        # whose shadows may reach into it.
        sun_dir = self.lights.sun_dir
        if n and sun_dir is not None and self.lod.cull:
            elev = max(float(sun_dir[2]), 0.1)
            reach = np.minimum(body_h * np.sqrt(1 - elev ** 2) / elev, 30.0)
            shifted = centres - np.outer(reach / 2, np.r_[sun_dir[:2], 0.0] / max(np.linalg.norm(sun_dir[:2]), 1e-6))
            casts = draw_mask & lod.in_frustum(shifted, radius + reach / 2, view, focal, w, h,
                                               camera.near, min(camera.far, self.shadow_distance))
        else:
            casts = draw_mask
        # Nearest the sun first: the shadow map's early depth test then skips
        # the texels a crowd already shades (the map's depths do not depend on the order).
        toward_sun = -(centres @ np.asarray(sun_dir, np.float64)) if n and sun_dir is not None else None
        s_order, s_starts = lod.group_by_level(lod.shadow_levels(levels, self.lod), casts, n_levels,
                                               distance=toward_sun)
        return {"n": n, "centres": centres, "radius": radius, "draw_mask": draw_mask,
                "in_view": in_view, "drawn": drawn, "order": order, "starts": starts, "casts": casts,
                "s_order": s_order, "s_starts": s_starts}

    def _shadow_pass(self, plan: dict, camera: CameraView, view, focal: float, time, s_base: int):
        """The sun's shadow map; returns (light view-projection, texel, scale of the map used, texels used)."""
        ctx, mgl = self.ctx, self._moderngl
        w, h = self.width, self.height
        sun_dir = self.lights.sun_dir
        light_vp, texel, shadow_scale, used = np.eye(4), 1.0, 1.0, 0
        if sun_dir is None or not self.shadows:
            return light_vp, texel, shadow_scale, used
        centres, radius = plan["centres"], plan["radius"]
        lo, hi = self._scenery_box
        if plan["n"]:
            a_lo = centres.min(0) - radius.max()
            a_hi = centres.max(0) + radius.max()
            lo, hi = np.minimum(lo, a_lo), np.maximum(hi, a_hi)
        if not np.isfinite(lo).all():
            lo, hi = np.array([-10.0, -10.0, 0.0]), np.array([10.0, 10.0, 2.0])
        corners = shadows.frustum_corners(camera.cam_to_world, focal, w, h, camera.near,
                                          min(camera.far, self.shadow_distance))
        light_vp, texel = shadows.fit_light_matrix(sun_dir, lo, hi, corners, self.shadow_size)
        # Texels finer than a screen pixel at the nearest characters are
        # wasted fill: use only as much of the map as they need.
        footprint = shadows.pixel_footprint(centres[plan["drawn"]], view, focal) if plan["n"] else None
        used = shadows.used_size(texel * self.shadow_size, footprint, self.shadow_size)
        texel, shadow_scale = texel * self.shadow_size / used, used / self.shadow_size
        self.shadow_fbo.viewport = (0, 0, used, used)
        self.shadow_fbo.use()
        # Lookups stay inside the used square (bilinear reads one texel past it).
        edge = min(used + 1, self.shadow_size)
        self.shadow_fbo.clear(depth=1.0, viewport=(0, 0, edge, edge))
        ctx.enable(mgl.DEPTH_TEST | mgl.PROGRAM_POINT_SIZE)
        ctx.disable(mgl.CULL_FACE)         # both faces: thin open meshes still cast
        ctx.polygon_offset = (2.0, 4.0)
        _set(self.prog_shadow_scenery, "u_light_vp", light_vp)
        for d in self._scenery:
            _set(self.prog_shadow_scenery, "u_model", self._world(d, time))
            d.shadow_vao.render(mgl.TRIANGLES)
        _set(self.prog_shadow_char, "u_light_vp", light_vp)
        if self.atlas is not None:
            _set(self.prog_shadow_imp, "u_light_vp", light_vp)
            _set(self.prog_shadow_imp, "u_sun_dir", np.asarray(sun_dir, np.float32))
            _set(self.prog_imp_place, "u_view_dir", np.asarray(sun_dir, np.float32))
        self._draw_levels(self.prog_shadow_char, 1, plan["s_starts"], s_base, shadow_texel=texel)
        ctx.polygon_offset = (0.0, 0.0)
        return light_vp, texel, shadow_scale, used

    def _view_pass(self, plan: dict, camera: CameraView, view, proj, focal: float, time, shadow, flip_y: bool):
        """The view: background, scenery, then the characters level by level, into the offscreen targets."""
        ctx, mgl = self.ctx, self._moderngl
        light_vp, texel, shadow_scale, _ = shadow
        sun_dir = self.lights.sun_dir
        self.fbo.use()
        self.fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        # Integer and float targets cannot share a clear colour: clear each alone.
        self.fbo.color_mask = ((True,) * 4, (False,) * 4, (False,) * 4)
        bg = self.background / 255.0
        self.fbo.clear(float(bg[0]), float(bg[1]), float(bg[2]), 1.0)
        self.fbo.color_mask = ((False,) * 4, (False,) * 4, (True,) * 4)
        self.fbo.clear(float("inf"), 0.0, 0.0, 0.0)
        self.fbo.color_mask = ((True,) * 4,) * 3
        ctx.enable(mgl.DEPTH_TEST | mgl.PROGRAM_POINT_SIZE)
        self.shadow_tex.use(0)
        if self.atlas is not None:
            eye = np.asarray(camera.cam_to_world[3, :3], np.float32)
            _set(self.prog_imp_place, "u_eye", eye)
            _set(self.prog_imp, "u_eye", eye)
            _set(self.prog_imp_place, "u_view_dir", np.zeros(3, np.float32))
        for prog in self._lit_programs():
            _set(prog, "u_view", view)
            _set(prog, "u_proj", proj)
            _set(prog, "u_light_vp", light_vp)
            _set(prog, "u_shadow_texel", float(texel))
            _set(prog, "u_shadow_scale", float(shadow_scale))
            _set(prog, "u_sun", np.asarray(self.lights.sun, np.float32) if sun_dir is not None else np.zeros(3, np.float32))
        ctx.disable(mgl.CULL_FACE)
        # The Y flip mirrors the image, so counter-clockwise triangles arrive
        # clockwise: tell GL, or gl_FrontFacing (two-sided floors) is inverted.
        ctx.front_face = "cw" if flip_y else "ccw"
        for d in self._scenery:
            world = self._world(d, time)
            _set(self.prog_scenery, "u_model", world)
            _set(self.prog_scenery, "u_normal_m", np.linalg.inv(world[:3, :3]).T)
            _set(self.prog_scenery, "u_base_color", np.asarray(d.item.material.base_color, np.float32))
            _set(self.prog_scenery, "u_shape_id", int(d.item.shape_id))
            _set(self.prog_scenery, "u_has_tex", d.texture is not None)
            if d.texture is not None:
                d.texture.use(1)
                _set(self.prog_scenery, "u_tex", 1)
            d.vao.render(mgl.TRIANGLES)
        _set(self.prog_char, "u_focal_px", focal)
        self._draw_levels(self.prog_char, 0, plan["starts"], 0)
        ctx.front_face = "ccw"

    def _world(self, d: _SceneryDraw, time) -> np.ndarray:
        return d.item.local_to_world(time) if d.item.animated else d.world

    def _upload(self, records: np.ndarray) -> None:
        data = records.tobytes()
        need = max(len(data), 160)
        if self._instances is None or need > self._instance_capacity:
            if self._instances is not None:
                self._instances.release()
            self._instance_capacity = max(need, 2 * self._instance_capacity)
            self._instances = self.ctx.buffer(reserve=self._instance_capacity, dynamic=True)
        if data:
            self._instances.write(data)
        self._instances.bind_to_storage_buffer(0)

    def _upload_slots(self, slots: np.ndarray) -> None:
        """Write the draws' agent indices (view levels, then shadow casters)."""
        need = 4 * max(len(slots), 4)
        if self._slots is None or need > self._slot_capacity:
            if self._slots is not None:
                self._slots.release()
            self._slot_capacity = max(need, 2 * self._slot_capacity)
            self._slots = self.ctx.buffer(reserve=self._slot_capacity, dynamic=True)
        if len(slots):
            self._slots.write(np.asarray(slots, dtype=np.uint32).tobytes())
        self._slots.bind_to_storage_buffer(1)

    def _draw_levels(self, prog, which: int, starts: np.ndarray, base: int, shadow_texel: float = 0.0) -> None:
        """Instanced draws, one per level of detail (``which``: 0 view, 1 shadow)."""
        mgl = self._moderngl
        for level in range(self.lod.n_levels):
            count = int(starts[level + 1] - starts[level])
            if count == 0:
                continue
            _set(prog, "u_base", int(base + starts[level]))
            if level < self.lod.n_meshes:
                vao = self._body_vaos[level][which]
                if which == 1 and self._shadow_mesh_vao is not None \
                        and self.lod.mesh_levels[level][1] < self.lod.shadow_cell:
                    vao = self._shadow_mesh_vao
                # Closed meshes: skip back faces in the view (the Y flip reverses the winding).
                if which == 0:
                    self.ctx.enable(mgl.CULL_FACE)
                vao.render(mgl.TRIANGLES, instances=count)
                self.ctx.disable(mgl.CULL_FACE)
            elif level == self.lod.impostor_level:
                self._draw_impostors(which, int(base + starts[level]), count)
            else:
                _, k, splat = self.lod.point_levels[level - self.lod.first_point_level]
                k = min(int(k), len(self.body.points.vertices))
                _set(prog, "u_point_size", float(splat))
                _set(prog, "u_point_size_px", float(splat / shadow_texel) if shadow_texel else 1.0)
                self._body_vaos[-1][which].render(mgl.POINTS, vertices=k, instances=count)

    def _draw_impostors(self, which: int, first: int, count: int) -> None:
        """Place (compute pass) then draw the quads of ``count`` agents from slot ``first``."""
        mgl = self._moderngl
        if count > self._imp_capacity:
            self._imp_capacity = max(count, 2 * self._imp_capacity)
            quad = np.array([0, 1, 3, 0, 3, 2], np.int32)
            indices = (np.arange(self._imp_capacity, dtype=np.int32)[:, None] * 4 + quad).ravel()
            for obj in (*(self._imp_vaos or ()), self._imp_index):
                if obj is not None:
                    obj.release()
            self._imp_index = self.ctx.buffer(indices.tobytes())
            self._imp_vaos = tuple(self.ctx.vertex_array(prog, [], self._imp_index, 4, skip_errors=True)
                                   for prog in (self.prog_imp, self.prog_shadow_imp))
        # Shadow and view records go to different halves: the shadow draw may still be reading.
        record = 16 * shaders.IMPOSTOR_RECORD      # bytes: vec4s of four floats
        need = 2 * count * record
        if self._sprites is None or need > self._sprite_capacity:
            if self._sprites is not None:
                self._sprites.release()
            self._sprite_capacity = max(need, 2 * self._sprite_capacity)
            self._sprites = self.ctx.buffer(reserve=self._sprite_capacity)
        self._sprites.bind_to_storage_buffer(2)
        sprite_base = which * (self._sprite_capacity // (2 * record))
        cs = self.prog_imp_place
        _set(cs, "u_base", first)
        _set(cs, "u_count", count)
        _set(cs, "u_sprite_base", sprite_base)
        cs.run(group_x=(count + 63) // 64)
        self.ctx.memory_barrier()
        vao = self._imp_vaos[which]
        _set(vao.program, "u_base", first)
        _set(vao.program, "u_sprite_base", sprite_base)
        vao.render(mgl.TRIANGLES, vertices=6 * count)

    def release(self) -> None:
        """Free the GL objects (the context too when this renderer made it)."""
        for obj in (self.fbo, self.fbo_color, self.shadow_fbo, self.color_tex, self.id_tex, self.depth_lin_tex,
                    self.depth_rb, self.shadow_tex):
            obj.release()
        for buf in (self._instances, self._slots, getattr(self, "_sprites", None), getattr(self, "_imp_index", None)):
            if buf is not None:
                buf.release()
        if self.atlas is not None:
            self.atlas.texture.release()
            self.atlas.boxes.release()
            self.atlas.regions.release()
