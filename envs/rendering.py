"""Headless OpenGL backend selection and off-screen rendering.

The default is Mesa's EGL, which renders on a CPU-only machine (and fast on a GPU); OSMesa is
the fallback when no EGL library is found. MuJoCo reads ``MUJOCO_GL`` once, when it is first
imported, so ``imitate/__init__.py`` imports this module first; :func:`make_renderer` also
hands MuJoCo's renderer the selected backend's context explicitly, so a script that imported
``mujoco`` before ``imitate`` still renders headless.
"""

from __future__ import annotations

import ctypes.util
import os

from imitate.errors import ImitateError

BACKENDS = ("egl", "osmesa")
_LIBRARIES = {"egl": "EGL", "osmesa": "OSMesa"}
_INSTALL_HINT = (
    "install Mesa's EGL (apt-get install libegl1 libgl1-mesa-dri) and use MUJOCO_GL=egl, "
    "or OSMesa (apt-get install libosmesa6) and use MUJOCO_GL=osmesa"
)


def select_backend() -> str:
    """Set ``MUJOCO_GL`` to a usable headless backend and return it.

    Keeps a valid user choice; otherwise picks the first of ``BACKENDS`` whose library is found.

    Raises:
        ImitateError: ``MUJOCO_GL`` names a backend other than ``egl``, ``osmesa`` or ``glfw``.
    """
    chosen = os.environ.get("MUJOCO_GL", "").strip().lower()
    if chosen:
        if chosen not in (*BACKENDS, "glfw"):
            raise ImitateError(
                f"MUJOCO_GL={chosen!r} is not a usable backend; accepted: 'egl' (default, "
                f"headless, CPU or GPU), 'osmesa' (headless fallback) or 'glfw' (needs a display)"
            )
        return chosen
    found = [b for b in BACKENDS if ctypes.util.find_library(_LIBRARIES[b])]
    os.environ["MUJOCO_GL"] = found[0] if found else BACKENDS[0]
    return os.environ["MUJOCO_GL"]


BACKEND = select_backend()

import mujoco  # noqa: E402  (must follow the backend selection)
from mujoco.rendering.classic import gl_context  # noqa: E402


def _context_class() -> type:
    """MuJoCo's OpenGL context class of the selected backend."""
    if BACKEND == "egl":
        from mujoco.egl import GLContext
    elif BACKEND == "osmesa":
        from mujoco.osmesa import GLContext
    else:
        from mujoco.glfw import GLContext
    return GLContext


def make_renderer(
    model: mujoco.MjModel, height: int, width: int, shadows: bool = True
) -> mujoco.Renderer:
    """An off-screen renderer of ``height x width`` pixels, with a clear error when GL fails.

    ``shadows=False`` halves the cost of a frame on a CPU (Mesa llvmpipe); the robot's cameras
    can do without them, a video for people looks better with them.

    The model's off-screen buffer (``model.vis.global_.offheight/offwidth``) must be at least
    as large; ``imitate.envs.assembly`` sets it.

    Raises:
        ImitateError: the size is not positive or exceeds the off-screen buffer, or no OpenGL
            context could be created with the selected backend.
    """
    max_h, max_w = model.vis.global_.offheight, model.vis.global_.offwidth
    if not (0 < height <= max_h and 0 < width <= max_w):
        raise ImitateError(
            f"image size {width}x{height} is not accepted: width must be in 1..{max_w} "
            f"and height in 1..{max_h} (the model's off-screen buffer)"
        )
    try:
        gl_context.GLContext = _context_class()
        renderer = mujoco.Renderer(model, height=height, width=width)
    except Exception as err:  # the GL libraries raise a zoo of types (RuntimeError, OSError, ...)
        raise ImitateError(
            f"could not create an OpenGL context with MUJOCO_GL={BACKEND!r} ({err}); "
            + _INSTALL_HINT
        ) from err
    renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = shadows
    return renderer
