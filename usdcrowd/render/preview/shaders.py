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

vec3 shade(vec3 albedo, vec3 wp, vec3 n) {
    // Dome: the up-facing hemisphere sees all of the sky, a wall about half
    // of it plus some light bounced from the ground.
    vec3 c = albedo * u_sky * (0.6 + 0.4 * n.z);
    float ndl = dot(n, u_sun_dir);
    if (ndl > 0.0) c += albedo * u_sun * ndl * sun_visibility(wp, n);
    for (int i = 0; i < u_n_lamps; ++i) {
        vec3 d = u_lamp_pos[i].xyz - wp;
        float r2 = max(dot(d, d), 1e-4);
        vec3 l = d * inversesqrt(r2);
        float emit = u_lamp_dir[i].w > 0.5 ? max(dot(-l, u_lamp_dir[i].xyz), 0.0) : 1.0;
        c += albedo * u_lamp_rgb[i].rgb * max(dot(n, l), 0.0) * emit / r2;
    }
    return c * u_exposure;
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

// Joint j's picture for this view: the centre of its covered rectangle, the
// rectangle's half axes (world vectors), the atlas cell and rectangle, and
// the part's radius.
void impostor(int instance, int j, out vec3 centre, out vec3 right, out vec3 up, out vec2 cell, out vec4 box,
              out float radius) {
    int b = record(instance);
    vec4 c0 = inst[b + 3 * j], c1 = inst[b + 3 * j + 1], c2 = inst[b + 3 * j + 2];
    vec4 pc = vec4(u_part_centre[j].xyz, 1.0);
    vec3 joint = vec3(dot(pc, c0), dot(pc, c1), dot(pc, c2));
    float s = length(c0.xyz);
    mat3 rot = transpose(mat3(c0.xyz, c1.xyz, c2.xyz)) / s;
    vec3 d = dot(u_view_dir, u_view_dir) > 0.5 ? u_view_dir : normalize(u_eye - joint);
    vec3 dl = transpose(rot) * d;
    float az = atan(dl.y, dl.x);
    float el = asin(clamp(dl.z, -1.0, 1.0));
    int ia = int(mod(round(az * float(N_AZ) / 6.28318530718), float(N_AZ)));
    int ie = clamp(int(round((el - EL0) / EL_STEP)), 0, N_EL - 1);
    float e = EL0 + float(ie) * EL_STEP;
    float r = u_part_centre[j].w;
    float hw = r * MARGIN * s;
    float hh = (u_part_half_height[j] * cos(e) + r * abs(sin(e))) * MARGIN * s;
    vec3 up_axis = rot[2], facing = rot[0];
    vec3 u = normalize(up_axis - dot(up_axis, d) * d + LEAN * (facing - dot(facing, d) * d));
    vec3 rt = cross(u, d);
    box = texelFetch(u_cell_box, ivec2(ia, j * N_EL + ie), 0);
    vec2 mid = 0.5 * (box.xy + box.zw), half_k = 0.5 * (box.zw - box.xy);
    centre = joint + mid.x * hw * rt + mid.y * hh * u;
    right = half_k.x * hw * rt;
    up = half_k.y * hh * u;
    cell = vec2(float(ia), float(j * N_EL + ie));
    radius = r * s;
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

float impostor_alpha(sampler2D atlas, vec2 cell, vec2 local_uv, out vec3 normal) {
    vec4 t = texture(atlas, impostor_coord(atlas, cell, local_uv));
    normal = t.rgb * 2.0 - 1.0;
    return t.a;
}
"""

# Placing a joint's picture takes trigonometry and a table lookup: done once
# per part in a compute pass (threaded on a software renderer too), not once
# per corner. Each sprite record is 4 vec4: centre and radius, the half axes
# right and up with the atlas cell in their w, and the covered rectangle.
IMPOSTOR_CS = VERSION + """
layout(local_size_x = 64) in;
""" + INSTANCES + IMPOSTOR_CONSTANTS + IMPOSTOR_PLACE + """
layout(std430, binding = 2) writeonly buffer Sprites { vec4 sprite_out[]; };
uniform int u_count;              // parts to place: three per agent
uniform int u_sprite_base;        // first record written

void main() {
    int k = int(gl_GlobalInvocationID.x);
    if (k >= u_count) return;
    vec3 centre, right, up;
    vec2 cell;
    vec4 box;
    float radius;
    impostor(k / 3, k % 3, centre, right, up, cell, box, radius);
    int o = (u_sprite_base + k) * 4;
    sprite_out[o] = vec4(centre, radius);
    sprite_out[o + 1] = vec4(right, cell.x);
    sprite_out[o + 2] = vec4(up, cell.y);
    sprite_out[o + 3] = box;
}
"""

IMPOSTOR_QUAD = """
layout(std430, binding = 2) readonly buffer Sprites { vec4 sprite[]; };
uniform int u_sprite_base;

// Corner of part quad gl_VertexID / 4 (indexed draw, no instancing: Mesa's
// software pipeline runs its whole front end once per instance).
void quad_corner(out vec3 wp, out vec2 local_uv, out vec2 cell, out float radius, out int part) {
    part = gl_VertexID >> 2;
    vec2 corner = vec2(float(gl_VertexID & 1), float((gl_VertexID >> 1) & 1));
    int o = (u_sprite_base + part) * 4;
    vec4 s0 = sprite[o], s1 = sprite[o + 1], s2 = sprite[o + 2], box = sprite[o + 3];
    vec2 q = corner * 2.0 - 1.0;
    wp = s0.xyz + q.x * s1.xyz + q.y * s2.xyz;
    local_uv = mix(box.xy, box.zw, corner) * 0.5 + 0.5;
    cell = vec2(s1.w, s2.w);
    radius = s0.w;
}
"""

IMPOSTOR_VS = VERSION + INSTANCES + IMPOSTOR_QUAD + """
uniform mat4 u_view;
uniform mat4 u_proj;
out vec3 v_world;
out vec2 v_uv;
out float v_z;
flat out vec2 v_cell;
flat out mat3 v_rot;
flat out float v_radius;
flat out vec3 v_palette[5];
flat out uint v_id;

void main() {
    vec3 wp;
    int part;
    quad_corner(wp, v_uv, v_cell, v_radius, part);
    int b = record(part / 3), j = part % 3;
    vec3 c0 = inst[b + 3 * j].xyz, c1 = inst[b + 3 * j + 1].xyz, c2 = inst[b + 3 * j + 2].xyz;
    v_rot = transpose(mat3(c0, c1, c2)) / length(c0);
    for (int k = 0; k < 5; ++k) v_palette[k] = inst[b + 9 + k].rgb;
    v_id = inst_u[b + 9].w;
    vec4 vp = u_view * vec4(wp, 1.0);
    gl_Position = u_proj * vp;
    v_world = wp;
    v_z = -vp.z;
}
"""

IMPOSTOR_FS = VERSION + LIGHTING + OUTPUTS + IMPOSTOR_CONSTANTS + IMPOSTOR_SAMPLE + """
uniform sampler2D u_atlas;
uniform sampler2D u_regions;      // the atlas's palette-row weights (impostors.ImpostorAtlas.regions)
in vec3 v_world;
in vec2 v_uv;
in float v_z;
flat in vec2 v_cell;
flat in mat3 v_rot;
flat in float v_radius;
flat in vec3 v_palette[5];
flat in uint v_id;

void main() {
    vec3 n_local;
    float alpha = impostor_alpha(u_atlas, v_cell, v_uv, n_local);
    if (alpha < 0.5) discard;
    // Weights were drawn over a cleared (zero) background, as coverage was: undo the edge blend.
    vec4 r = texture(u_regions, impostor_coord(u_atlas, v_cell, v_uv)) / alpha;
    vec3 v_color = r.x * v_palette[0] + r.y * v_palette[1] + r.z * v_palette[2] + r.w * v_palette[3]
                 + max(1.0 - r.x - r.y - r.z - r.w, 0.0) * v_palette[4];
    vec3 n = normalize(v_rot * n_local);
    // The quad runs through the joint's middle: look the shadow up on the
    // sun's side of the body, or half of it would shadow itself.
    vec3 wp = v_world + u_sun_dir * v_radius;
    o_color = vec4(srgb_encode(shade(v_color, wp, n)), 1.0);
    o_id = v_id;
    o_depth = v_z;
}
"""

SHADOW_IMPOSTOR_VS = VERSION + INSTANCES + IMPOSTOR_QUAD + """
uniform mat4 u_light_vp;
out vec2 v_uv;
flat out vec2 v_cell;

void main() {
    vec3 wp;
    float radius;
    int part;
    quad_corner(wp, v_uv, v_cell, radius, part);
    gl_Position = u_light_vp * vec4(wp, 1.0);
}
"""

SHADOW_IMPOSTOR_FS = VERSION + IMPOSTOR_CONSTANTS + IMPOSTOR_SAMPLE + """
uniform sampler2D u_atlas;
in vec2 v_uv;
flat in vec2 v_cell;

void main() {
    vec3 n;
    if (impostor_alpha(u_atlas, v_cell, v_uv, n) < 0.5) discard;
}
"""

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
