"""GLSL sources of the preview, assembled from shared pieces.

Matrix convention: numpy matrices are row-vector ones (``p' = p @ M``, as in
USD) and are uploaded unchanged. moderngl fills a ``mat4`` column by column,
so GLSL sees ``transpose(M)`` and ``u_m * v`` is exactly ``v @ M``.

Colour: shading is done in linear RGB and encoded to sRGB in the fragment
shader with the exact piecewise sRGB curve (IEC 61966-2-1), so 8-bit frames
come straight out of the read-back. ``tests/render/preview/test_preview.py``
checks the encoding against colour-science to within one code value.
"""

from __future__ import annotations

VERSION = "#version 430\n"

# Per-agent record: 14 vec4. Rows 0-8: for joint j, the three columns
# (c = 0, 1, 2) of its 4x4 row-vector skinning matrix, so a point's world
# coordinate c is dot(vec4(p, 1), column c). Rows 9-13: linear RGB of the
# palette's rows (top, trousers, skin, hair, shoes, eye whites, face); row 9's .w holds the
# agent's track id (uint bits). See instancing.pack_instances.
# Draws reach the records through a list of agent indices (``slot``).
INSTANCE_STRIDE = 16

INSTANCES = """
layout(std430, binding = 0) readonly buffer Instances { vec4 inst[]; };
// The same buffer seen as integers: the id is read as bits, never as a float
// (a small uint's bits are a denormal, which a flush-to-zero unit would zero).
layout(std430, binding = 0) readonly buffer InstanceIds { uvec4 inst_u[]; };
// Which agent each drawn instance is: one record per agent is uploaded per
// frame, and every draw (a level of detail, in the view or the shadow map)
// is a contiguous run of this list starting at u_base.
layout(std430, binding = 1) readonly buffer Slots { uint slot[]; };
uniform int u_base;

int record(int k) { return int(slot[u_base + k]) * %d; }
""" % INSTANCE_STRIDE

SKINNING = INSTANCES + """
// r, r45: the vertex's weights of palette rows 0-3 and 4-5 (row 6 has the rest).
void skin(vec3 p, vec3 n, vec3 w, vec4 r, vec2 r45, out vec3 wp, out vec3 wn, out vec3 color, out uint id) {
    int b = record(gl_InstanceID);
    // Linear blend skinning with dense weights over the three joints.
    vec4 c0 = w.x * inst[b + 0] + w.y * inst[b + 3] + w.z * inst[b + 6];
    vec4 c1 = w.x * inst[b + 1] + w.y * inst[b + 4] + w.z * inst[b + 7];
    vec4 c2 = w.x * inst[b + 2] + w.y * inst[b + 5] + w.z * inst[b + 8];
    vec4 hp = vec4(p, 1.0);
    wp = vec3(dot(hp, c0), dot(hp, c1), dot(hp, c2));
    // Joints are rotation times uniform scale, so the linear part maps normals.
    wn = vec3(dot(n, c0.xyz), dot(n, c1.xyz), dot(n, c2.xyz));
    color = r.x * inst[b + 9].rgb + r.y * inst[b + 10].rgb + r.z * inst[b + 11].rgb + r.w * inst[b + 12].rgb
          + r45.x * inst[b + 13].rgb + r45.y * inst[b + 14].rgb
          + max(1.0 - r.x - r.y - r.z - r.w - r45.x - r45.y, 0.0) * inst[b + 15].rgb;
    id = inst_u[b + 9].w;
}
"""

# The exact piecewise sRGB curve (IEC 61966-2-1): frames leave the shaders encoded.
SRGB_ENCODE = """
vec3 srgb_encode(vec3 c) {
    c = clamp(c, 0.0, 1.0);
    return mix(12.92 * c, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), c));
}
"""

LIGHTING = SRGB_ENCODE + """
uniform vec3 u_sun_dir;          // unit, from the surface towards the sun
uniform vec3 u_sun;              // sun irradiance * rgb / pi (radiance per unit albedo)
uniform vec3 u_sky;              // dome radiance * rgb
uniform int u_n_lamps;
uniform vec4 u_lamp_pos[8];      // xyz world position
uniform vec4 u_lamp_rgb[8];      // rgb * emitted power factor / pi; E = rgb / d^2
uniform vec4 u_lamp_dir[8];      // xyz emission axis, w = 1 for one-sided (rect, disk) lamps
uniform sampler2DShadow u_shadow;
uniform mat4 u_light_vp;
uniform float u_shadow_texel;    // world size of one shadow-map texel, metres
uniform float u_shadow_scale;    // fraction of the map's side this frame uses (from its corner)
uniform float u_exposure;

float sun_visibility(vec3 wp, vec3 n) {
    // Normal offset by a couple of texels: no acne on floors, no peter-panning of feet.
    vec4 lp = u_light_vp * vec4(wp + n * (2.0 * u_shadow_texel), 1.0);
    vec3 s = lp.xyz / lp.w * 0.5 + 0.5;
    if (any(lessThan(s, vec3(0.0))) || any(greaterThan(s, vec3(1.0)))) return 1.0;
    // One hardware-filtered comparison (bilinear over 2x2 texels): soft
    // enough for a preview, and a quarter of the cost of a 4-tap kernel on
    // a software rasteriser.
    return texture(u_shadow, vec3(s.xy * u_shadow_scale, s.z));
}

// Lit colour given the sun's visibility at the point (0 in shadow, 1 lit).
vec3 shade_seen(vec3 albedo, vec3 wp, vec3 n, float sun_seen) {
    // Dome: the up-facing hemisphere sees all of the sky, a wall about half
    // of it plus some light bounced from the ground.
    vec3 c = albedo * u_sky * (0.6 + 0.4 * n.z);
    c += albedo * u_sun * max(dot(n, u_sun_dir), 0.0) * sun_seen;
    for (int i = 0; i < u_n_lamps; ++i) {
        vec3 d = u_lamp_pos[i].xyz - wp;
        float r2 = max(dot(d, d), 1e-4);
        vec3 l = d * inversesqrt(r2);
        float emit = u_lamp_dir[i].w > 0.5 ? max(dot(-l, u_lamp_dir[i].xyz), 0.0) : 1.0;
        c += albedo * u_lamp_rgb[i].rgb * max(dot(n, l), 0.0) * emit / r2;
    }
    return c * u_exposure;
}

vec3 shade(vec3 albedo, vec3 wp, vec3 n) {
    return shade_seen(albedo, wp, n, dot(n, u_sun_dir) > 0.0 ? sun_visibility(wp, n) : 0.0);
}
"""

OUTPUTS = """
layout(location = 0) out vec4 o_color;
layout(location = 1) out uint o_id;
layout(location = 2) out float o_depth;
"""

# ---------------------------------------------------------------- characters
CHARACTER_VS = VERSION + SKINNING + """
uniform mat4 u_view;
uniform mat4 u_proj;
uniform float u_focal_px;        // pixels per metre at 1 m depth (points only)
uniform float u_point_size;      // world size of a point splat, metres (points only)
in vec3 in_pos;
in vec3 in_nrm;
in vec3 in_w;
in vec4 in_region;
in vec2 in_region45;
out vec3 v_world;
out vec3 v_nrm;
out vec3 v_color;
out float v_z;
flat out uint v_id;

void main() {
    vec3 wp, wn, color; uint id;
    skin(in_pos, in_nrm, in_w, in_region, in_region45, wp, wn, color, id);
    vec4 vp = u_view * vec4(wp, 1.0);
    gl_Position = u_proj * vp;
    // Used only when drawing GL_POINTS (seed 004's point-based LOD).
    gl_PointSize = max(1.0, u_point_size * u_focal_px / max(-vp.z, 1e-3));
    v_world = wp;
    v_nrm = wn;
    v_color = color;
    v_z = -vp.z;
    v_id = id;
}
"""

CHARACTER_FS = VERSION + LIGHTING + OUTPUTS + """
in vec3 v_world;
in vec3 v_nrm;
in vec3 v_color;
in float v_z;
flat in uint v_id;

void main() {
    vec3 n = normalize(v_nrm);
    o_color = vec4(srgb_encode(shade(v_color, v_world, n)), 1.0);
    o_id = v_id;
    o_depth = v_z;
}
"""

# ------------------------------------------------------------------- scenery
SCENERY_VS = VERSION + """
uniform mat4 u_model;
uniform mat3 u_normal_m;
uniform mat4 u_view;
uniform mat4 u_proj;
in vec3 in_pos;
in vec3 in_nrm;
in vec2 in_uv;
out vec3 v_world;
out vec3 v_nrm;
out vec2 v_uv;
out float v_z;

void main() {
    vec4 wp = u_model * vec4(in_pos, 1.0);
    vec4 vp = u_view * wp;
    gl_Position = u_proj * vp;
    v_world = wp.xyz;
    v_nrm = u_normal_m * in_nrm;
    v_uv = in_uv;
    v_z = -vp.z;
}
"""

SCENERY_FS = VERSION + LIGHTING + OUTPUTS + """
uniform vec3 u_base_color;
uniform uint u_shape_id;
uniform bool u_has_tex;
uniform sampler2D u_tex;          // sRGB texture: sampling linearises it
in vec3 v_world;
in vec3 v_nrm;
in vec2 v_uv;
in float v_z;

void main() {
    vec3 n = normalize(v_nrm);
    if (!gl_FrontFacing) n = -n;   // open meshes (floors, planes) are seen from both sides
    vec3 albedo = u_has_tex ? texture(u_tex, v_uv).rgb : u_base_color;
    o_color = vec4(srgb_encode(shade(albedo, v_world, n)), 1.0);
    o_id = u_shape_id;
    o_depth = v_z;
}
"""

# ---------------------------------------------------------------- impostors
# Per-joint impostors (see impostors.py; the constants must match it).
IMPOSTOR_CONSTANTS = """
const int N_AZ = 16;
const int N_EL = 6;
const float EL0 = radians(-10.0);
const float EL_STEP = radians(20.0);
const float LEAN = 0.05;
const float MARGIN = 1.04;
"""

IMPOSTOR_PLACE = """
uniform vec4 u_part_centre[3];        // bind-space cylinder centre, w: radius
uniform float u_part_half_height[3];
uniform vec3 u_eye;                   // perspective views: the camera's position
uniform vec3 u_view_dir;              // orthographic views (the sun): toward the viewer; else 0
uniform sampler2D u_cell_box;         // covered rectangle of each view, corner space

// Joint j's picture for this view, seen from where the viewer is.
struct Picture {
    vec3 joint;      // the part's cylinder centre, world
    vec3 rt, up;     // unit axes of the picture, world
    vec2 half_ext;   // half width and height of the cell's frame, metres
    vec3 d;          // toward the viewer
    vec2 cell;       // atlas cell (azimuth column, part-and-elevation row)
    vec4 box;        // covered rectangle, corner space
    mat3 rot;        // the joint's rotation, local to world
    float radius;    // metres
};

bool orthographic() { return dot(u_view_dir, u_view_dir) > 0.5; }

Picture picture(int b, int j) {
    Picture p;
    vec4 c0 = inst[b + 3 * j], c1 = inst[b + 3 * j + 1], c2 = inst[b + 3 * j + 2];
    vec4 pc = vec4(u_part_centre[j].xyz, 1.0);
    p.joint = vec3(dot(pc, c0), dot(pc, c1), dot(pc, c2));
    float s = length(c0.xyz);
    p.rot = transpose(mat3(c0.xyz, c1.xyz, c2.xyz)) / s;
    p.d = orthographic() ? u_view_dir : normalize(u_eye - p.joint);
    vec3 dl = transpose(p.rot) * p.d;
    float az = atan(dl.y, dl.x);
    float el = asin(clamp(dl.z, -1.0, 1.0));
    int ia = int(mod(round(az * float(N_AZ) / 6.28318530718), float(N_AZ)));
    int ie = clamp(int(round((el - EL0) / EL_STEP)), 0, N_EL - 1);
    float e = EL0 + float(ie) * EL_STEP;
    float r = u_part_centre[j].w;
    p.half_ext = vec2(r, u_part_half_height[j] * cos(e) + r * abs(sin(e))) * MARGIN * s;
    vec3 up_axis = p.rot[2], facing = p.rot[0];
    p.up = normalize(up_axis - dot(up_axis, p.d) * p.d + LEAN * (facing - dot(facing, p.d) * p.d));
    p.rt = cross(p.up, p.d);
    p.box = texelFetch(u_cell_box, ivec2(ia, j * N_EL + ie), 0);
    p.cell = vec2(float(ia), float(j * N_EL + ie));
    p.radius = r * s;
    return p;
}

// Where the line of sight through x meets the plane through o with normal n.
vec3 along_sight(vec3 x, vec3 o, vec3 n) {
    vec3 from = orthographic() ? x : u_eye;
    vec3 dir = orthographic() ? u_view_dir : x - u_eye;
    return from + dir * (dot(o - from, n) / dot(dir, n));
}

// Quaternion (xyz, w) of a rotation matrix (GLSL's m[column][row]).
vec4 quat_of(mat3 m) {
    float tr = m[0][0] + m[1][1] + m[2][2];
    if (tr > 0.0) {
        float s = 2.0 * sqrt(tr + 1.0);
        return vec4(m[1][2] - m[2][1], m[2][0] - m[0][2], m[0][1] - m[1][0], 0.25 * s * s) / s;
    }
    if (m[0][0] > m[1][1] && m[0][0] > m[2][2]) {
        float s = 2.0 * sqrt(1.0 + m[0][0] - m[1][1] - m[2][2]);
        return vec4(0.25 * s * s, m[1][0] + m[0][1], m[2][0] + m[0][2], m[1][2] - m[2][1]) / s;
    }
    if (m[1][1] > m[2][2]) {
        float s = 2.0 * sqrt(1.0 + m[1][1] - m[0][0] - m[2][2]);
        return vec4(m[1][0] + m[0][1], 0.25 * s * s, m[2][1] + m[1][2], m[2][0] - m[0][2]) / s;
    }
    float s = 2.0 * sqrt(1.0 + m[2][2] - m[0][0] - m[1][1]);
    return vec4(m[2][0] + m[0][2], m[2][1] + m[1][2], 0.25 * s * s, m[0][1] - m[1][0]) / s;
}
"""

IMPOSTOR_SAMPLE = """
vec2 impostor_coord(sampler2D atlas, vec2 cell, vec2 local_uv) {
    // Clamp half a texel inside the cell: linear filtering must not read the neighbours.
    vec2 size = vec2(textureSize(atlas, 0));
    vec2 grid = vec2(float(N_AZ), float(3 * N_EL));
    vec2 half_texel = 0.5 * grid / size;
    return (cell + clamp(local_uv, half_texel, 1.0 - half_texel)) / grid;
}

// The part's picture at this fragment, if it covers it (coverage in t.a).
bool covered(sampler2D atlas, vec2 cell, vec2 local_uv, out vec4 t, out vec2 coord) {
    t = vec4(0.0);
    coord = impostor_coord(atlas, cell, local_uv);
    if (any(lessThan(local_uv, vec2(0.0))) || any(greaterThan(local_uv, vec2(1.0)))) return false;
    t = texture(atlas, coord);
    return t.a >= 0.5;
}
"""

# Placing the pictures takes trigonometry and table lookups: done once per
# agent in a compute pass (threaded on a software renderer too), not once
# per corner. A character is one quad in the plane of its torso's picture,
# spanning the covered rectangles of all three pictures as seen from the
# viewer; for each corner the record holds where the line of sight through
# it meets each part's picture, so the fragment shader reads all three (a
# software rasteriser pays per triangle far more than per texture read).
# Record (IMPOSTOR_RECORD vec4): centre and torso radius; the quad's half
# axes right and up; the palette as half floats (rows 3-4); the joints'
# rotations as 16-bit quaternions and the three atlas cells in one uint
# (rows 5-6); the plane the quad's depth is taken from (row 7: normal,
# offset); per corner the three parts' picture coordinates (rows 8-15).
# The flat rows are packed because a software rasteriser's front end pays
# for every scalar a vertex carries to the fragments (about a third of an
# impostor's set-up went to unpacked palettes and rotations).
IMPOSTOR_RECORD = 16

# The depth an impostor writes. Its quad lies in the torso's picture plane,
# which leans toward a camera looking down: the legs' pixels came out nearer
# than the legs, and a character just behind a wall showed them through it.
# The depth comes from an upright plane instead (the quad's own plane once
# the view is steep enough for an upright plane to be seen edge on): across
# the body's front in a perspective view; through its axis in the sun's
# view, so its shadow neither reaches through a wall nor falls on the body's
# own lit side, where the figure looks the sun's visibility up.
IMPOSTOR_DEPTH_PLANE = """
const float UPRIGHT_UNTIL = 0.906;    // sin(65 deg): upright below this elevation of the view
const float LEAN_FROM = 0.996;        // sin(85 deg): the quad's own plane above this

// (unit normal toward the viewer, offset): the plane's points x have dot(normal, x) = offset.
vec4 depth_plane(Picture legs, Picture torso, Picture head) {
    vec3 n = torso.d;
    vec3 up = torso.rot[2];
    float sin_e = dot(n, up);
    vec3 level = n - sin_e * up;
    float lean = smoothstep(UPRIGHT_UNTIL, LEAN_FROM, abs(sin_e));
    vec3 normal = dot(level, level) > 1e-8 ? normalize(mix(normalize(level), n, lean)) : n;
    // Through the front of the widest part, so no foot or hand stands in front of it.
    float front = orthographic() ? 0.0 : max(max(legs.radius, torso.radius), head.radius);
    return vec4(normal, dot(normal, torso.joint) + front);
}
"""

IMPOSTOR_CS = VERSION + """
layout(local_size_x = 64) in;
""" + INSTANCES + IMPOSTOR_CONSTANTS + IMPOSTOR_PLACE + IMPOSTOR_DEPTH_PLANE + """
layout(std430, binding = 2) writeonly buffer Sprites { vec4 sprite_out[]; };
layout(std430, binding = 2) writeonly buffer SpriteBits { uvec4 sprite_bits_out[]; };
uniform int u_count;              // agents to place
uniform int u_sprite_base;        // first record written

void main() {
    int k = int(gl_GlobalInvocationID.x);
    if (k >= u_count) return;
    int b = record(k);
    Picture p[3];
    for (int j = 0; j < 3; ++j) p[j] = picture(b, j);
    // The quad lies in the torso's picture plane and covers every part's
    // covered rectangle projected onto it along the lines of sight.
    vec3 o = p[1].joint, n = p[1].d, R = p[1].rt, U = p[1].up;
    vec2 lo = vec2(1e30), hi = vec2(-1e30);
    for (int j = 0; j < 3; ++j) {
        for (int c = 0; c < 4; ++c) {
            vec2 q = mix(p[j].box.xy, p[j].box.zw, vec2(float(c & 1), float(c >> 1)));
            vec3 x = p[j].joint + q.x * p[j].half_ext.x * p[j].rt + q.y * p[j].half_ext.y * p[j].up;
            vec3 h = along_sight(x, o, n) - o;
            vec2 xy = vec2(dot(h, R), dot(h, U));
            lo = min(lo, xy);
            hi = max(hi, xy);
        }
    }
    vec2 mid = 0.5 * (lo + hi), half_k = 0.5 * (hi - lo);
    int w = (u_sprite_base + k) * """ + str(IMPOSTOR_RECORD) + """;
    vec3 centre = o + mid.x * R + mid.y * U;
    sprite_out[w] = vec4(centre, p[1].radius);
    sprite_out[w + 1] = vec4(half_k.x * R, 0.0);
    sprite_out[w + 2] = vec4(half_k.y * U, 0.0);
    vec3 pal[5];
    for (int i = 0; i < 5; ++i) pal[i] = inst[b + 9 + i].rgb;
    sprite_bits_out[w + 3] = uvec4(packHalf2x16(pal[0].rg), packHalf2x16(vec2(pal[0].b, pal[1].r)),
                                   packHalf2x16(pal[1].gb), packHalf2x16(pal[2].rg));
    sprite_bits_out[w + 4] = uvec4(packHalf2x16(vec2(pal[2].b, pal[3].r)), packHalf2x16(pal[3].gb),
                                   packHalf2x16(pal[4].rg), packHalf2x16(vec2(pal[4].b, 0.0)));
    vec4 q0 = quat_of(p[0].rot), q1 = quat_of(p[1].rot), q2 = quat_of(p[2].rot);
    uint cells = 0u;
    for (int j = 0; j < 3; ++j) cells |= (uint(p[j].cell.x) | (uint(p[j].cell.y) << 4)) << (9 * j);
    sprite_bits_out[w + 5] = uvec4(packSnorm2x16(q0.xy), packSnorm2x16(q0.zw), packSnorm2x16(q1.xy),
                                   packSnorm2x16(q1.zw));
    sprite_bits_out[w + 6] = uvec4(packSnorm2x16(q2.xy), packSnorm2x16(q2.zw), cells, 0u);
    sprite_out[w + 7] = depth_plane(p[0], p[1], p[2]);
    for (int c = 0; c < 4; ++c) {
        vec2 q = vec2(float(c & 1), float(c >> 1)) * 2.0 - 1.0;
        vec3 corner = centre + q.x * half_k.x * R + q.y * half_k.y * U;
        vec2 uv[3];
        for (int j = 0; j < 3; ++j) {
            vec3 h = along_sight(corner, p[j].joint, p[j].d) - p[j].joint;
            uv[j] = vec2(dot(h, p[j].rt), dot(h, p[j].up)) / p[j].half_ext * 0.5 + 0.5;
        }
        sprite_out[w + 8 + 2 * c] = vec4(uv[0], uv[1]);
        sprite_out[w + 9 + 2 * c] = vec4(uv[2], 0.0, 0.0);
    }
}
"""

IMPOSTOR_QUAD = """
layout(std430, binding = 2) readonly buffer Sprites { vec4 sprite[]; };
layout(std430, binding = 2) readonly buffer SpriteBits { uvec4 sprite_bits[]; };
uniform int u_sprite_base;

// Corner of agent gl_VertexID / 4's quad (indexed draw, no instancing:
// Mesa's software pipeline runs its whole front end once per instance).
void quad_corner(out vec3 wp, out vec4 uv01, out vec2 uv2, out uint cells, out int agent, out int o) {
    agent = gl_VertexID >> 2;
    int c = gl_VertexID & 3;
    vec2 q = vec2(float(c & 1), float(c >> 1)) * 2.0 - 1.0;
    o = (u_sprite_base + agent) * """ + str(IMPOSTOR_RECORD) + """;
    wp = sprite[o].xyz + q.x * sprite[o + 1].xyz + q.y * sprite[o + 2].xyz;
    cells = sprite_bits[o + 6].z;
    uv01 = sprite[o + 8 + 2 * c];
    uv2 = sprite[o + 9 + 2 * c].xy;
}
"""

IMPOSTOR_VARYINGS = """
in vec3 v_world;
in vec4 v_uv01;
in vec2 v_uv2;
in float v_z;
flat in uint v_cells;        // the three parts' atlas cells, 9 bits each (impostor_cell)
"""

IMPOSTOR_VS = VERSION + LIGHTING + INSTANCES + IMPOSTOR_QUAD + """
uniform mat4 u_view;
uniform mat4 u_proj;
uniform vec3 u_eye;
""" + IMPOSTOR_VARYINGS.replace("in ", "out ") + """
out float v_sun_seen;
flat out uvec4 v_quat01;    // quaternions of the legs and the torso, 16-bit (packSnorm2x16)
flat out uvec2 v_quat2;     // the head's
flat out uvec4 v_palette_a; // the five palette colours as fifteen half floats
flat out uvec4 v_palette_b;
flat out uint v_id;

void main() {
    vec3 wp;
    int agent, o;
    quad_corner(wp, v_uv01, v_uv2, v_cells, agent, o);
    v_quat01 = sprite_bits[o + 5];
    v_quat2 = sprite_bits[o + 6].xy;
    v_palette_a = sprite_bits[o + 3];
    v_palette_b = sprite_bits[o + 4];
    float radius = sprite[o].w;
    // The sun's visibility on the body's axis at this corner's height,
    // looked up on the sun's side of the body: a figure under 100 px is
    // shaded from the head's and the feet's, where a lookup per fragment
    // cost a quarter of its drawing.
    float up = float((gl_VertexID & 3) >> 1) * 2.0 - 1.0;
    vec3 axis = sprite[o].xyz + up * sprite[o + 2].xyz;
    v_sun_seen = sun_visibility(axis + u_sun_dir * radius, u_sun_dir);
    v_id = inst_u[record(agent) + 9].w;
    vec4 vp = u_view * vec4(wp, 1.0);
    vec4 clip = u_proj * vp;
    // Depth from where this corner's line of sight meets the depth plane
    // (IMPOSTOR_DEPTH_PLANE); x, y and w stay the quad's, so the pictures
    // are read where the quad places them.
    vec4 plane = sprite[o + 7];
    vec3 ray = wp - u_eye;
    float along = dot(plane.xyz, ray);
    float s = along < -1e-6 * length(ray) ? (plane.w - dot(plane.xyz, u_eye)) / along : 0.0;
    vec3 dp = s > 0.0 ? u_eye + ray * s : wp;     // the quad's own depth with the eye at the plane or past it
    vec4 dvp = u_view * vec4(dp, 1.0);
    vec4 dclip = u_proj * dvp;
    gl_Position = vec4(clip.xy, dclip.z / dclip.w * clip.w, clip.w);
    v_world = wp;
    v_z = -dvp.z;
}
"""

# The frontmost part's picture at a fragment: the head, then the torso (its
# arms hang over the hips), then the legs.
IMPOSTOR_PICK = """
// Part j's atlas cell: (azimuth column, part-and-elevation row).
vec2 impostor_cell(int j) {
    uint c = v_cells >> (9 * j);
    return vec2(float(c & 15u), float((c >> 4) & 31u));
}

int pick(sampler2D atlas, out vec4 t, out vec2 coord) {
    if (covered(atlas, impostor_cell(2), v_uv2, t, coord)) return 2;
    if (covered(atlas, impostor_cell(1), v_uv01.zw, t, coord)) return 1;
    if (covered(atlas, impostor_cell(0), v_uv01.xy, t, coord)) return 0;
    return -1;
}
"""

IMPOSTOR_FS = (VERSION + LIGHTING + OUTPUTS + IMPOSTOR_CONSTANTS + IMPOSTOR_SAMPLE + IMPOSTOR_VARYINGS
               + IMPOSTOR_PICK + """
uniform sampler2D u_atlas;
uniform sampler2D u_regions;      // the atlas's palette-row weights (impostors.ImpostorAtlas.regions)
in float v_sun_seen;
flat in uvec4 v_quat01;
flat in uvec2 v_quat2;
flat in uvec4 v_palette_a;
flat in uvec4 v_palette_b;
flat in uint v_id;

vec3 rotate(vec4 q, vec3 v) { return v + 2.0 * cross(q.xyz, cross(q.xyz, v) + q.w * v); }

vec4 joint_quat(int j) {
    uvec2 q = j == 0 ? v_quat01.xy : (j == 1 ? v_quat01.zw : v_quat2);
    return vec4(unpackSnorm2x16(q.x), unpackSnorm2x16(q.y));
}

// The palette's five colours weighted by the picture's region weights r (the fifth takes the rest).
vec3 palette_colour(vec4 r) {
    vec2 a = unpackHalf2x16(v_palette_a.x), b = unpackHalf2x16(v_palette_a.y);
    vec2 c = unpackHalf2x16(v_palette_a.z), d = unpackHalf2x16(v_palette_a.w);
    vec2 e = unpackHalf2x16(v_palette_b.x), f = unpackHalf2x16(v_palette_b.y);
    vec2 g = unpackHalf2x16(v_palette_b.z), h = unpackHalf2x16(v_palette_b.w);
    return r.x * vec3(a, b.x) + r.y * vec3(b.y, c) + r.z * vec3(d, e.x) + r.w * vec3(e.y, f)
         + max(1.0 - r.x - r.y - r.z - r.w, 0.0) * vec3(g, h.x);
}

void main() {
    vec4 t;
    vec2 coord;
    int j = pick(u_atlas, t, coord);
    if (j < 0) discard;
    // Weights were drawn over a cleared (zero) background, as coverage was: undo the edge blend.
    vec4 r = texture(u_regions, coord) / t.a;
    vec3 n = normalize(rotate(joint_quat(j), t.rgb * 2.0 - 1.0));
    o_color = vec4(srgb_encode(shade_seen(palette_colour(r), v_world, n, v_sun_seen)), 1.0);
    o_id = v_id;
    o_depth = v_z;
}
""")

SHADOW_IMPOSTOR_VS = VERSION + INSTANCES + IMPOSTOR_QUAD + """
uniform mat4 u_light_vp;
uniform vec3 u_sun_dir;           // toward the sun
""" + IMPOSTOR_VARYINGS.replace("in ", "out ") + """

void main() {
    vec3 wp;
    int agent, o;
    quad_corner(wp, v_uv01, v_uv2, v_cells, agent, o);
    // Depth from the depth plane (IMPOSTOR_DEPTH_PLANE): along the sun's
    // direction, which an orthographic view maps to the same texel.
    vec4 plane = sprite[o + 7];
    float along = dot(plane.xyz, u_sun_dir);
    vec3 dp = along > 1e-6 ? wp + u_sun_dir * ((plane.w - dot(plane.xyz, wp)) / along) : wp;
    gl_Position = u_light_vp * vec4(dp, 1.0);
    v_world = wp;
    v_z = 0.0;
}
"""

SHADOW_IMPOSTOR_FS = (VERSION + IMPOSTOR_CONSTANTS + IMPOSTOR_SAMPLE + IMPOSTOR_VARYINGS + IMPOSTOR_PICK + """
uniform sampler2D u_atlas;

void main() {
    vec4 t;
    vec2 coord;
    if (pick(u_atlas, t, coord) < 0) discard;
}
""")

# ------------------------------------------------------------------- shadows
SHADOW_CHARACTER_VS = VERSION + SKINNING + """
uniform mat4 u_light_vp;
uniform float u_point_size_px;     // splat size in shadow texels (points only)
in vec3 in_pos;
in vec3 in_nrm;
in vec3 in_w;

void main() {
    vec3 wp, wn, color; uint id;
    skin(in_pos, in_nrm, in_w, vec4(1.0, 0.0, 0.0, 0.0), vec2(0.0), wp, wn, color, id);
    gl_Position = u_light_vp * vec4(wp, 1.0);
    gl_PointSize = max(1.0, u_point_size_px);
}
"""

SHADOW_SCENERY_VS = VERSION + """
uniform mat4 u_model;
uniform mat4 u_light_vp;
in vec3 in_pos;

void main() {
    gl_Position = u_light_vp * (u_model * vec4(in_pos, 1.0));
}
"""

DEPTH_ONLY_FS = VERSION + """
void main() {}
"""

# ------------------------------------------------------------------ overlays
OVERLAY_VS = VERSION + """
uniform mat4 u_view;
uniform mat4 u_proj;
in vec3 in_pos;
in vec4 in_color;
in vec2 in_uv;
out vec4 v_color;
out vec2 v_uv;

void main() {
    gl_Position = u_proj * (u_view * vec4(in_pos, 1.0));
    v_color = in_color;
    v_uv = in_uv;
}
"""

OVERLAY_FS = VERSION + SRGB_ENCODE + """
uniform bool u_has_tex;
uniform sampler2D u_tex;
in vec4 v_color;
in vec2 v_uv;
layout(location = 0) out vec4 o_color;

void main() {
    vec4 c = u_has_tex ? v_color * texture(u_tex, v_uv) : v_color;
    if (c.a <= 0.0) discard;
    // Blending happens on encoded values: overlays are annotations, not light.
    o_color = vec4(srgb_encode(c.rgb), c.a);
}
"""
