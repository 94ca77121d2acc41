"""OpenGL contexts for the preview: headless through EGL, or a glfw window.

moderngl and glfw are optional (``usdcrowd[preview]``), so they are imported
inside the functions; every failure becomes one :class:`UsdcrowdError` line
that says what to install.
"""

from __future__ import annotations

import os

from ...core.errors import UsdcrowdError

# OpenGL 4.3 is the floor: the per-instance bone matrices live in a shader
# storage buffer. Mesa's llvmpipe offers 4.5 core.
GL_VERSION = 430

_PIP_HINT = "install usdcrowd[preview] (pip install 'usdcrowd[preview]')"
_APT_HINT = ("no OpenGL context could be made; for headless rendering install Mesa's EGL "
             "(apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri libgles2)")


def require_moderngl():
    """Import moderngl or raise a UsdcrowdError naming the extra to install."""
    try:
        import moderngl
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise UsdcrowdError(f"the preview needs moderngl ({exc}); {_PIP_HINT}") from None
    return moderngl


def headless_context():
    """A standalone OpenGL 4.3+ context through EGL (no display, no GPU needed).

    Returns
    -------
    moderngl.Context

    Raises
    ------
    UsdcrowdError
        If moderngl is missing or EGL cannot make a context (with the apt
        packages that provide Mesa's EGL).
    """
    moderngl = require_moderngl()
    errors = []
    # EGL first: it needs no display and works on Mesa's llvmpipe. An X
    # display (e.g. Xvfb) is the fallback where EGL is missing.
    backends = ["egl"] + (["x11"] if os.environ.get("DISPLAY") else [])
    for backend in backends:
        try:
            ctx = moderngl.create_standalone_context(require=GL_VERSION, backend=backend)
        except Exception as exc:  # glcontext raises bare Exceptions
            errors.append(f"{backend}: {' '.join(str(exc).split())[:120]}")
            continue
        return ctx
    raise UsdcrowdError(f"{_APT_HINT} ({'; '.join(errors)})")


def window_context(width: int, height: int, title: str = "usdcrowd preview"):
    """Open a glfw window with an OpenGL 4.3 core context.

    Returns
    -------
    window : glfw window handle
    ctx : moderngl.Context
        Wraps the window's context (its default framebuffer is the screen).

    Raises
    ------
    UsdcrowdError
        If glfw is missing, there is no display, or no context can be made.
    """
    moderngl = require_moderngl()
    try:
        import glfw
    except ImportError as exc:  # pragma: no cover
        raise UsdcrowdError(f"the preview window needs glfw ({exc}); {_PIP_HINT}") from None
    if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
        raise UsdcrowdError("no display for a window (DISPLAY is unset); use -o to render headless, "
                            "or run under Xvfb (apt-get install xvfb; xvfb-run usdcrowd preview ...)")
    if not glfw.init():
        raise UsdcrowdError("glfw could not initialise the display; use -o to render headless")
    glfw.window_hint(glfw.CONTEXT_VERSION_MAJOR, GL_VERSION // 100)
    glfw.window_hint(glfw.CONTEXT_VERSION_MINOR, GL_VERSION // 10 % 10)
    glfw.window_hint(glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE)
    glfw.window_hint(glfw.OPENGL_FORWARD_COMPAT, True)
    glfw.window_hint(glfw.RESIZABLE, False)     # the offscreen targets have a fixed size
    window = glfw.create_window(int(width), int(height), title, None, None)
    if not window:
        glfw.terminate()
        raise UsdcrowdError(f"glfw could not open an OpenGL {GL_VERSION / 100:.1f} window; {_APT_HINT}")
    glfw.make_context_current(window)
    glfw.swap_interval(0)
    try:
        ctx = moderngl.create_context(require=GL_VERSION)
    except Exception as exc:
        glfw.destroy_window(window)
        glfw.terminate()
        raise UsdcrowdError(f"the window's OpenGL context is unusable ({exc}); {_APT_HINT}") from None
    return window, ctx
