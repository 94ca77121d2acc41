"""Impostors: a small character drawn as one quad carrying its three joints' pictures.

A character between the point levels and the full mesh costs a software
rasteriser mostly triangle set-up, so it is drawn from pictures instead
(Tecchia et al. 2002 draw whole crowds this way; seed 004 keeps points for the
smallest). The body is rigid per joint (legs, torso, head), so each joint has
its own pictures, placed by that joint's skinning matrix: the pose, the
height and the heading are exact, only the view is quantised. The three
pictures share one quad per character (two triangles, where a quad per
joint cost three times the set-up): it lies in the torso's picture plane,
spans the three pictures' covered rectangles, and each fragment reads the
head's, the torso's and the legs' pictures where its line of sight meets
them, keeping the first that covers it (``shaders.IMPOSTOR_CS`` places them).

The atlas holds, for each joint's part of the body, views from
``N_AZIMUTH`` directions around it and ``N_ELEVATION`` heights. A texel
stores the part's surface normal in the joint's frame (rgb) and coverage
(alpha), so the shader lights the picture with the stage's sun, sky and
lamps and tints it with the agent's colour, as it does the meshes.

Framing of a view (shared by the atlas and the shader, so they agree): the
part's bounding cylinder (axis along the joint's Z) seen along ``d`` spans
``2 r`` across and ``2 (h cos e + r sin e)`` along its projected axis, where
``e`` is the view's elevation and ``h`` the cylinder's half height.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

N_AZIMUTH = 16
N_ELEVATION = 6
# Elevation of each row's view, radians: from slightly below to straight down.
ELEVATIONS = np.radians(np.linspace(-10.0, 90.0, N_ELEVATION))
# Texels per side of one view. The legs, the part with the coarsest texels,
# get 1.6 cm a texel: an impostor up to 100 px tall shows no texel larger
# than a pixel (LodSettings's mesh level starts there).
CELL = 96
# Leans the picture's "up" toward the joint's facing, so a view straight down
# the axis still has a defined orientation.
FACING_LEAN = 0.05
MARGIN = 1.04             # the cylinder's outline plus antialiasing room


@dataclass
class Part:
    """The body triangles of one joint and their bounding cylinder (bind space)."""

    faces: np.ndarray       # (f, 3) int
    centre: np.ndarray      # (3,) float
    radius: float
    half_height: float


def body_parts(points: np.ndarray, faces: np.ndarray, weights: np.ndarray) -> list[Part]:
    """Split the body by each triangle's dominant joint.

    Parameters
    ----------
    points : (v, 3) float
        Bind pose.
    faces : (f, 3) int
    weights : (v, 3) float
        Dense weights of the three joints.
    """
    owner = np.argmax(np.asarray(weights)[np.asarray(faces)].sum(axis=1), axis=1)
    parts = []
    for j in range(weights.shape[1]):
        f = np.asarray(faces)[owner == j]
        p = np.asarray(points, dtype=np.float64)[np.unique(f)] if len(f) else np.zeros((1, 3))
        lo, hi = p.min(0), p.max(0)
        centre = (lo + hi) / 2.0
        radius = float(np.hypot(p[:, 0] - centre[0], p[:, 1] - centre[1]).max())
        parts.append(Part(f, centre, max(radius, 1e-3), max(float(hi[2] - lo[2]) / 2.0, 1e-3)))
    return parts


def view_direction(azimuth: float, elevation: float) -> np.ndarray:
    """Unit vector (3,) from a part toward the viewer, in the joint's frame."""
    return np.array([np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth), np.sin(elevation)])


def view_basis(d: np.ndarray, part: Part) -> tuple[np.ndarray, np.ndarray, float, float]:
    """Right and up vectors of the picture seen along ``d``, and its half extents (metres)."""
    z, x = np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])
    up = (z - z.dot(d) * d) + FACING_LEAN * (x - x.dot(d) * d)
    up /= np.linalg.norm(up)
    right = np.cross(up, d)
    sin_e = abs(float(d[2]))
    cos_e = np.sqrt(max(1.0 - sin_e ** 2, 0.0))
    return right, up, part.radius * MARGIN, (part.half_height * cos_e + part.radius * sin_e) * MARGIN


ATLAS_VS = """#version 430
uniform vec3 u_centre;
uniform vec3 u_right;       // already divided by the half extents
uniform vec3 u_up;
uniform vec3 u_dir;         // toward the viewer
uniform float u_depth_range;
in vec3 in_pos;
in vec3 in_nrm;
in vec4 in_region;
out vec3 v_nrm;
out vec4 v_region;
void main() {
    vec3 p = in_pos - u_centre;
    gl_Position = vec4(dot(p, u_right), dot(p, u_up), -dot(p, u_dir) / u_depth_range, 1.0);
    v_nrm = in_nrm;
    v_region = in_region;
}
"""

ATLAS_FS = """#version 430
in vec3 v_nrm;
in vec4 v_region;
layout(location = 0) out vec4 o_color;
layout(location = 1) out vec4 o_region;
void main() {
    o_color = vec4(normalize(v_nrm) * 0.5 + 0.5, 1.0);
    o_region = v_region;
}
"""


@dataclass
class ImpostorAtlas:
    """The pictures and the framing constants the shaders need.

    Attributes
    ----------
    texture : moderngl.Texture
        ``(N_AZIMUTH * CELL, 3 * N_ELEVATION * CELL)`` RGBA8; row block
        ``part * N_ELEVATION + elevation``, column ``azimuth``.
    regions : moderngl.Texture
        The same layout: weights of palette rows 0-3 (row 4 has the rest; the
        face is drawn as skin), so an impostor wears what the mesh it replaces wears.
    boxes : moderngl.Texture
        ``(N_AZIMUTH, 3 * N_ELEVATION)`` RGBA32F: each view's covered
        rectangle ``(x0, y0, x1, y1)`` in the quad's [-1, 1] corner space,
        so a quad spans its picture and no more (two thirds of the
        cylinder's outline on average: fewer fragments to discard).
    parts : list of Part
    """

    texture: object
    boxes: object
    parts: list
    regions: object = None

    def uniforms(self) -> dict:
        """Per-part centre (w: radius) and half height, for the impostor shaders."""
        centre = np.zeros((3, 4), np.float32)
        half_h = np.zeros(3, np.float32)
        for j, p in enumerate(self.parts):
            centre[j, :3], centre[j, 3], half_h[j] = p.centre, p.radius, p.half_height
        return {"u_part_centre": centre, "u_part_half_height": half_h}


def build_atlas(ctx, points: np.ndarray, faces: np.ndarray, weights: np.ndarray, normals: np.ndarray,
                regions: np.ndarray | None = None) -> ImpostorAtlas:
    """Render every part from every view into one texture.

    Parameters
    ----------
    ctx : moderngl.Context
    points, normals : (v, 3) float
        Bind pose and vertex normals.
    faces : (f, 3) int
    weights : (v, 3) float
        Dense joint weights.
    regions : (v, 6) float, optional
        Weights of palette rows 0-5 (BodyGeometry's last columns, row 6 has
        the rest); row 0 if omitted. The atlas keeps rows 0-3 (row 4 has the
        rest): rows 5 and 6, the eyes and mouth, a pixel or two where
        impostors stand in, take the skin's row 2.
    """
    import moderngl

    if regions is None:
        regions = np.tile(np.eye(6)[0], (len(points), 1))
    regions = np.array(regions, dtype=np.float64)
    face = regions[:, 5] + np.clip(1.0 - regions.sum(axis=1), 0.0, 1.0)
    regions = regions[:, :4]
    regions[:, 2] += face

    parts = body_parts(points, faces, weights)
    width, height = N_AZIMUTH * CELL, len(parts) * N_ELEVATION * CELL
    tex = ctx.texture((width, height), 4, dtype="f1")
    region_tex = ctx.texture((width, height), 4, dtype="f1")
    depth = ctx.depth_renderbuffer((width, height))
    fbo = ctx.framebuffer([tex, region_tex], depth)
    prog = ctx.program(vertex_shader=ATLAS_VS, fragment_shader=ATLAS_FS)
    vbo = ctx.buffer(np.concatenate([points, normals, regions], 1).astype(np.float32).tobytes())
    fbo.use()
    fbo.clear(0.5, 0.5, 1.0, 0.0, depth=1.0)      # transparent, normals facing out of the picture
    # Weights start at zero outside the body, as coverage does (the shader divides one by the other).
    blank = ctx.framebuffer([region_tex])
    blank.clear(0.0, 0.0, 0.0, 0.0)
    blank.release()
    fbo.use()
    ctx.enable(moderngl.DEPTH_TEST)
    ctx.disable(moderngl.CULL_FACE)
    try:
        for j, part in enumerate(parts):
            if not len(part.faces):
                continue
            ibo = ctx.buffer(part.faces.astype(np.int32).tobytes())
            vao = ctx.vertex_array(prog, [(vbo, "3f 3f 4f", "in_pos", "in_nrm", "in_region")], ibo)
            prog["u_centre"].value = tuple(part.centre)
            prog["u_depth_range"].value = 4.0 * (part.radius + part.half_height)
            for e, elev in enumerate(ELEVATIONS):
                for a in range(N_AZIMUTH):
                    d = view_direction(2.0 * np.pi * a / N_AZIMUTH, elev)
                    right, up, hw, hh = view_basis(d, part)
                    prog["u_right"].value = tuple(right / hw)
                    prog["u_up"].value = tuple(up / hh)
                    prog["u_dir"].value = tuple(d)
                    fbo.viewport = (a * CELL, (j * N_ELEVATION + e) * CELL, CELL, CELL)
                    vao.render(moderngl.TRIANGLES)
            vao.release()
            ibo.release()
    finally:
        fbo.viewport = (0, 0, width, height)
        for obj in (fbo, depth, prog, vbo):
            obj.release()
    for t in (tex, region_tex):
        t.filter = (moderngl.LINEAR, moderngl.LINEAR)
        t.repeat_x = t.repeat_y = False
    rgba = np.frombuffer(tex.read(), np.uint8).reshape(height, width, 4)
    boxes = ctx.texture((N_AZIMUTH, len(parts) * N_ELEVATION), 4, cell_boxes(rgba[..., 3]).tobytes(), dtype="f4")
    boxes.filter = (moderngl.NEAREST, moderngl.NEAREST)
    return ImpostorAtlas(tex, boxes, parts, region_tex)


def cell_boxes(alpha: np.ndarray) -> np.ndarray:
    """Covered rectangle of every view, (rows, N_AZIMUTH, 4) float32 in [-1, 1] corner space.

    Parameters
    ----------
    alpha : (rows * CELL, N_AZIMUTH * CELL) uint8
        The atlas's coverage, GL row order (row 0 at the bottom).
    """
    rows = alpha.shape[0] // CELL
    cells = (alpha > 0).reshape(rows, CELL, N_AZIMUTH, CELL).transpose(0, 2, 1, 3)   # (row, az, y, x)
    out = np.tile(np.array([-1.0, -1.0, 1.0, 1.0], np.float32), (rows, N_AZIMUTH, 1))
    for axis, (lo_k, hi_k) in ((3, (0, 2)), (2, (1, 3))):      # x from the columns, y from the rows
        hit = cells.any(axis=5 - axis)
        any_hit = hit.any(axis=-1)
        first = np.argmax(hit, axis=-1)
        last = hit.shape[-1] - 1 - np.argmax(hit[..., ::-1], axis=-1)
        # One texel of slack each side for linear filtering.
        out[..., lo_k] = np.where(any_hit, np.maximum(first - 1, 0) / CELL * 2.0 - 1.0, -1.0)
        out[..., hi_k] = np.where(any_hit, np.minimum(last + 2, CELL) / CELL * 2.0 - 1.0, 1.0)
    return out
