"""The interactive preview window (glfw): play, pause, scrub, switch cameras, fly.

Keys
----
Space        play / pause
Left, Right  one frame back / forward (hold Shift: ten)
Home, End    first / last frame
C            next stage camera (leaves the free-fly camera)
F            free-fly camera from the current view (again: back to the stage camera)
W A S D      fly forward, left, back, right; Q, E: down, up (Shift: faster)
right drag   look around (free-fly)
L            level of detail on / off
H            shadows on / off
Esc          quit

Click or drag in the strip at the bottom of the window to scrub. The title
bar shows the time code, the camera, the frame rate and the characters drawn
at each level of detail. Colour is sRGB-encoded in the fragment shader (the
same shader as the headless frames), so the window shows what -o writes.
"""

from __future__ import annotations

import time as _time

import numpy as np

from ...core.view import CameraView, look_at

SCRUB_PX = 14           # height of the scrub strip, pixels


def look_at_matrix(eye: np.ndarray, yaw: float, pitch: float) -> np.ndarray:
    """(4, 4) camera-to-world of a free-fly camera: Z up, yaw about Z, pitch up from the horizon.

    The camera looks down its local -Z with +Y up (USD's convention).
    """
    forward = np.array([np.cos(pitch) * np.cos(yaw), np.cos(pitch) * np.sin(yaw), np.sin(pitch)])
    return look_at(eye, np.asarray(eye, dtype=np.float64) + forward)[0]


class FreeFly:
    """A camera driven by the keyboard and mouse, starting from a CameraView."""

    def __init__(self, start: CameraView):
        self.view = start
        self.eye = start.position.copy()
        forward = -start.cam_to_world[2, :3]
        self.yaw = float(np.arctan2(forward[1], forward[0]))
        self.pitch = float(np.arcsin(np.clip(forward[2], -1.0, 1.0)))

    def move(self, local: np.ndarray, dt: float, speed: float) -> None:
        """Move by ``local`` (right, up, back) axes, metres per second times ``speed``."""
        m = look_at_matrix(self.eye, self.yaw, self.pitch)
        self.eye = self.eye + (np.asarray(local, dtype=np.float64) @ m[:3, :3]) * speed * dt

    def turn(self, dx: float, dy: float, sensitivity: float = 0.004) -> None:
        self.yaw -= dx * sensitivity
        self.pitch = float(np.clip(self.pitch - dy * sensitivity, -1.5, 1.5))

    def camera(self, time: float) -> CameraView:
        v = self.view
        return CameraView("free-fly", float(time), look_at_matrix(self.eye, self.yaw, self.pitch), v.focal_length,
                          v.horizontal_aperture, v.vertical_aperture, v.near, v.far)


class Viewer:
    """State of the preview window; :func:`run_viewer` drives it."""

    def __init__(self, renderer, times: np.ndarray, camera: str | None, window):
        self.r = renderer
        self.times = np.asarray(times, dtype=np.float64)
        self.index = 0
        self.playing = True
        self.cameras = renderer.scene.camera_paths
        self.cam_index = self.cameras.index(camera) if camera in self.cameras else 0
        self.fly: FreeFly | None = None
        self.window = window
        self.fps = renderer.scene.fps or 24.0
        self._last_mouse = None
        self._clock = _time.perf_counter()
        self._accum = 0.0
        self.stats = {}
        self.draw_fps = 0.0

    @property
    def time(self) -> float:
        return float(self.times[self.index])

    def camera(self) -> CameraView:
        if self.fly is not None:
            return self.fly.camera(self.time)
        return self.r.scene.camera(self.cameras[self.cam_index], self.time)

    # ------------------------------------------------------------- input
    def on_key(self, key: int, mods: int) -> bool:
        """Handle one key press; False to quit."""
        import glfw

        step = 10 if mods & glfw.MOD_SHIFT else 1
        if key == glfw.KEY_ESCAPE:
            return False
        if key == glfw.KEY_SPACE:
            self.playing = not self.playing
        elif key == glfw.KEY_RIGHT:
            self.seek(self.index + step)
        elif key == glfw.KEY_LEFT:
            self.seek(self.index - step)
        elif key == glfw.KEY_HOME:
            self.seek(0)
        elif key == glfw.KEY_END:
            self.seek(len(self.times) - 1)
        elif key == glfw.KEY_C and self.cameras:
            self.fly = None
            self.cam_index = (self.cam_index + 1) % len(self.cameras)
        elif key == glfw.KEY_F:
            self.fly = None if self.fly is not None else FreeFly(self.camera())
        elif key == glfw.KEY_L:
            from dataclasses import replace

            self.r.lod = replace(self.r.lod, enabled=not self.r.lod.enabled)
        elif key == glfw.KEY_H:
            self.r.shadows = not self.r.shadows
            if not self.r.shadows:
                self.r.shadow_fbo.clear(depth=1.0)
        return True

    def seek(self, index: int) -> None:
        self.index = int(np.clip(index, 0, len(self.times) - 1))
        self._accum = 0.0

    def scrub_to(self, x: float, width: int) -> None:
        self.seek(round(x / max(width - 1, 1) * (len(self.times) - 1)))

    def advance(self) -> None:
        """Play at the shot's frame rate (frames are skipped when drawing is slower)."""
        now = _time.perf_counter()
        dt, self._clock = now - self._clock, now
        if self.playing and len(self.times) > 1:
            self._accum += dt * self.fps
            steps = int(self._accum)
            if steps:
                self._accum -= steps
                self.index = (self.index + steps) % len(self.times)
        return dt

    def fly_keys(self, dt: float) -> None:
        import glfw

        if self.fly is None:
            return
        w = self.window
        local = np.zeros(3)
        for key, axis in ((glfw.KEY_W, (0, 0, -1)), (glfw.KEY_S, (0, 0, 1)), (glfw.KEY_A, (-1, 0, 0)),
                          (glfw.KEY_D, (1, 0, 0)), (glfw.KEY_E, (0, 1, 0)), (glfw.KEY_Q, (0, -1, 0))):
            if glfw.get_key(w, key) == glfw.PRESS:
                local += axis
        if local.any():
            fast = glfw.get_key(w, glfw.KEY_LEFT_SHIFT) == glfw.PRESS
            self.fly.move(local, dt, 12.0 if fast else 3.0)

    def title(self) -> str:
        cam = "free-fly" if self.fly is not None else (self.cameras[self.cam_index] if self.cameras else "-")
        s = self.stats
        lod = (f"full {s.get('full', 0)} clustered {s.get('coarse', 0)} impostors {s.get('impostors', 0)} "
               f"points {s.get('points', 0)}") if s else ""
        state = "playing" if self.playing else "paused"
        return (f"usdcrowd preview  t={self.time:g} ({self.index + 1}/{len(self.times)}, {state})  {cam}  "
                f"{self.draw_fps:.1f} fps  {lod}")


def _draw_scrub_bar(ctx, width: int, fraction: float) -> None:
    """The scrub strip at the bottom of the screen: scissored clears, no geometry."""
    screen = ctx.screen
    screen.use()
    screen.scissor = (0, 0, width, SCRUB_PX)
    screen.clear(0.12, 0.12, 0.12, 1.0)
    screen.scissor = (0, 3, max(1, int(round(fraction * width))), SCRUB_PX - 6)
    screen.clear(0.85, 0.7, 0.2, 1.0)
    screen.scissor = None


def run_viewer(scene, width: int, height: int, *, times=None, camera: str | None = None, overlays=None,
               lod_settings=None, exposure: float = 1.0, max_frames: int | None = None,
               keys: tuple = (), screenshot: str | None = None) -> int:
    """Open the window and run until it is closed; returns the exit code.

    Parameters
    ----------
    scene : ShotScene
    width, height : int
        Size of the drawing (the window adds the scrub strip below).
    times : array of float, optional
        Time codes to play (default: the stage's range).
    max_frames : int, optional
        Stop after drawing this many frames (tests, smoke runs).
    keys : tuple of (frame, glfw key)
        Key presses to replay before drawing the given frame (tests).
    screenshot : str, optional
        Save the window's last picture (drawing and scrub strip) to this PNG.

    Raises
    ------
    UsdcrowdError
        Without a display or an OpenGL context.
    """
    import glfw

    from .context import window_context
    from .renderer import PreviewRenderer

    window, ctx = window_context(width, height + SCRUB_PX)
    try:
        r = PreviewRenderer(scene, width, height, ctx=ctx, lod_settings=lod_settings, overlays=overlays,
                            exposure=exposure)
        viewer = Viewer(r, scene.time_codes if times is None else times, camera, window)
        running = _connect_input(window, viewer, width, height)
        drawn = 0
        while running[0] and not glfw.window_should_close(window):
            for frame, key in keys:
                if frame == drawn and not viewer.on_key(key, 0):
                    running[0] = False
            _draw_frame(ctx, window, r, viewer, width, height, drawn)
            glfw.set_window_title(window, viewer.title())
            glfw.poll_events()
            drawn += 1
            if max_frames is not None and drawn >= max_frames:
                break
        if screenshot:
            _save_screenshot(ctx, width, height, screenshot)
        r.release()
    finally:
        glfw.destroy_window(window)
        glfw.terminate()
    return 0


def _connect_input(window, viewer: Viewer, width: int, height: int) -> list[bool]:
    """Hand the window's keys, clicks and mouse moves to ``viewer``; the flag returned turns False to quit."""
    import glfw

    running = [True]
    dragging = [False]

    def on_key(win, key, scancode, action, mods):
        if action in (glfw.PRESS, glfw.REPEAT) and not viewer.on_key(key, mods):
            running[0] = False

    def on_button(win, button, action, mods):
        x, y = glfw.get_cursor_pos(win)
        if button == glfw.MOUSE_BUTTON_LEFT:
            dragging[0] = action == glfw.PRESS and y >= height
            if dragging[0]:
                viewer.scrub_to(x, width)
        if button == glfw.MOUSE_BUTTON_RIGHT:
            viewer._last_mouse = (x, y) if action == glfw.PRESS else None

    def on_move(win, x, y):
        if dragging[0]:
            viewer.scrub_to(x, width)
        if viewer._last_mouse is not None and viewer.fly is not None:
            lx, ly = viewer._last_mouse
            viewer.fly.turn(x - lx, y - ly)
            viewer._last_mouse = (x, y)

    glfw.set_key_callback(window, on_key)
    glfw.set_mouse_button_callback(window, on_button)
    glfw.set_cursor_pos_callback(window, on_move)
    return running


def _draw_frame(ctx, window, r, viewer: Viewer, width: int, height: int, drawn: int) -> None:
    """Step the clock and the free-fly camera, draw the frame and the scrub strip, show them; time the drawing."""
    import glfw

    dt = viewer.advance()
    viewer.fly_keys(dt)
    t0 = _time.perf_counter()
    cam = viewer.camera()
    poses = r.poses(viewer.time)
    # The drawing goes above the scrub strip: blit into that part of the screen.
    viewer.stats = r.draw(poses, cam, viewer.time, flip_y=False)
    ctx.screen.use()
    _blit_above(ctx, r, height)
    _draw_scrub_bar(ctx, width, viewer.index / max(len(viewer.times) - 1, 1))
    glfw.swap_buffers(window)
    ctx.finish()
    spent = _time.perf_counter() - t0
    viewer.draw_fps = 0.9 * viewer.draw_fps + 0.1 / max(spent, 1e-6) if drawn else 1 / max(spent, 1e-6)


def _save_screenshot(ctx, width: int, height: int, path: str) -> None:
    """The window's last picture (drawing and scrub strip) as a PNG."""
    from .output import write_png

    ctx.screen.use()
    img = np.frombuffer(ctx.screen.read(components=3), np.uint8).reshape(height + SCRUB_PX, width, 3)
    write_png(img[::-1], path)


def _blit_above(ctx, renderer, height: int) -> None:
    """Copy the offscreen colour onto the screen above the scrub strip.

    moderngl's copy_framebuffer needs equal sizes, so the colour texture is
    drawn with a one-triangle pass into a viewport that leaves the strip.
    """
    prog = getattr(renderer, "_blit_prog", None)
    if prog is None:
        prog = ctx.program(
            vertex_shader="""#version 430
            out vec2 uv;
            void main() {
                vec2 p = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2);
                uv = p;
                gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
            }""",
            fragment_shader="""#version 430
            uniform sampler2D tex;
            in vec2 uv;
            out vec4 o;
            void main() { o = texture(tex, uv); }""")
        renderer._blit_prog = prog
        renderer._blit_vao = ctx.vertex_array(prog, [])
    import moderngl

    screen = ctx.screen
    screen.use()
    screen.viewport = (0, SCRUB_PX, renderer.width, height)
    ctx.disable(moderngl.DEPTH_TEST)
    renderer.color_tex.use(0)
    prog["tex"].value = 0
    renderer._blit_vao.render(moderngl.TRIANGLES, vertices=3)
    screen.viewport = (0, 0, renderer.width, height + SCRUB_PX)
    ctx.enable(moderngl.DEPTH_TEST)
