"""Headless OpenGL backends and off-screen rendering.

Importing this module sets nothing and loads neither MuJoCo nor OpenGL. The backend is chosen
when the first renderer is made (:func:`make_renderer`): the one ``MUJOCO_GL`` names, or with
``MUJOCO_GL`` unset Mesa's EGL (renders on a CPU-only machine, fast on a GPU) and OSMesa where
no EGL library is installed. :func:`make_renderer` hands MuJoCo that backend's context itself,
so a library user renders headless whether ``mujoco`` was imported first or not, with
``MUJOCO_GL`` unset or set.

MuJoCo reads ``MUJOCO_GL`` once, when ``mujoco`` is imported, and a value whose library is
missing breaks that import; the ``imitate`` command calls :func:`import_mujoco` before anything
else imports it.

Rendering releases the GIL: :func:`in_thread` renders ahead of a caller that does other work
meanwhile, and :func:`interleaved` renders the frames of a sequence in several threads at once,
each thread with its own OpenGL context.
"""

from __future__ import annotations

import contextlib
import ctypes.util
import functools
import logging
import os
import queue
import sys
import threading
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, TypeVar, cast

from imitate.errors import ImitateError

if TYPE_CHECKING:
    import mujoco

log = logging.getLogger(__name__)
T = TypeVar("T")

BACKENDS = ("egl", "osmesa")  # headless, in order of preference
_LIBRARIES = {"egl": "EGL", "osmesa": "OSMesa"}
_INSTALL = {
    "egl": "install Mesa's EGL (apt-get install libegl1 libgl1-mesa-dri)",
    "osmesa": "install OSMesa (apt-get install libosmesa6)",
}


@functools.cache
def _installed(backend: str) -> bool:
    return ctypes.util.find_library(_LIBRARIES[backend]) is not None


def backend() -> str:
    """The backend to render with: ``MUJOCO_GL``'s, or with it unset the first of
    :data:`BACKENDS` whose library is installed.

    Raises:
        ImitateError: ``MUJOCO_GL`` names a backend other than ``egl``, ``osmesa`` or
            ``glfw``, or one whose library is not installed, or none is installed; the message
            names the fix.
    """
    chosen = os.environ.get("MUJOCO_GL", "").strip().lower()
    if chosen and chosen not in (*BACKENDS, "glfw"):
        raise ImitateError(
            f"MUJOCO_GL={chosen!r} is not a usable backend; accepted: 'egl' (default, "
            f"headless, CPU or GPU), 'osmesa' (headless fallback) or 'glfw' (needs a display)"
        )
    if chosen in BACKENDS and not _installed(chosen):
        others = [b for b in BACKENDS if b != chosen and _installed(b)]
        instead = f", or unset MUJOCO_GL to render with {others[0]}" if others else ""
        raise ImitateError(
            f"MUJOCO_GL={chosen!r} but lib{_LIBRARIES[chosen]} is not installed: "
            f"{_INSTALL[chosen]}{instead}"
        )
    if not chosen:
        found = [b for b in BACKENDS if _installed(b)]
        if not found:
            raise ImitateError(
                f"no headless OpenGL library (libEGL or libOSMesa) is installed: "
                f"{_INSTALL['egl']}, or {_INSTALL['osmesa']} and set MUJOCO_GL=osmesa"
            )
        chosen = found[0]
    return chosen


def import_mujoco() -> None:
    """Import MuJoCo for a program (the ``imitate`` command) with ``MUJOCO_GL`` set to
    :func:`backend`. Without a usable backend MuJoCo is imported without OpenGL and
    ``MUJOCO_GL`` left as it was: what does not render works (``--help``, most stages) and
    the first :func:`make_renderer` reports the problem.
    """
    given = os.environ.get("MUJOCO_GL")
    try:
        chosen = backend()
    except ImitateError:
        chosen = None
    os.environ["MUJOCO_GL"] = chosen or "disable"
    import mujoco  # noqa: F401

    if chosen is None:  # as it was, for make_renderer to report
        del os.environ["MUJOCO_GL"]
        if given is not None:
            os.environ["MUJOCO_GL"] = given


@functools.cache
def _context_class() -> type:
    """MuJoCo's OpenGL context class of :func:`backend` (fixed once the first is made)."""
    chosen = backend()
    log.debug("rendering with MUJOCO_GL=%s", chosen)
    if chosen == "egl":
        from mujoco.egl import GLContext
    elif chosen == "osmesa":
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
        ImitateError: the size is not positive or exceeds the off-screen buffer, no backend is
            usable (see :func:`backend`), or no OpenGL context could be created with it.
    """
    import mujoco

    max_h, max_w = model.vis.global_.offheight, model.vis.global_.offwidth
    if not (0 < height <= max_h and 0 < width <= max_w):
        raise ImitateError(
            f"image size {width}x{height} is not accepted: width must be in 1..{max_w} "
            f"and height in 1..{max_h} (the model's off-screen buffer)"
        )
    chosen = backend()
    try:
        # The module of mujoco.Renderer (mujoco.renderer in 3.x) creates the context it names.
        sys.modules[mujoco.Renderer.__module__].gl_context.GLContext = _context_class()
        renderer = mujoco.Renderer(model, height=height, width=width)
    except Exception as err:  # the GL libraries raise a zoo of types (RuntimeError, OSError, ...)
        raise ImitateError(
            f"could not create an OpenGL context with MUJOCO_GL={chosen!r} ({err}); "
            f"{_INSTALL['egl']} and use MUJOCO_GL=egl, or {_INSTALL['osmesa']} and use "
            f"MUJOCO_GL=osmesa"
        ) from err
    renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = shadows
    return renderer



@contextlib.contextmanager
def in_thread(items: Callable[[], Iterator[T]], ahead: int) -> Iterator[Iterator[T]]:
    """Makes the items of the iterator ``items()`` in a thread of its own, up to ``ahead`` items
    ahead of the caller. On entering, the iterator over them, in order (the thread's error is
    raised there); on leaving, the thread stops. A renderer made in ``items()`` has its OpenGL
    context in that thread."""
    handed: queue.Queue = queue.Queue(ahead)
    stop = threading.Event()

    def hand(item) -> bool:
        while not stop.is_set():
            try:
                handed.put(item, timeout=0.1)
                return True
            except queue.Full:
                pass
        return False

    def make() -> None:
        try:
            for item in items():
                if not hand(item):
                    return
            hand(_END)
        except BaseException as err:  # raised again in the caller's thread
            hand(err)

    def received() -> Iterator[T]:
        while (item := handed.get()) is not _END:
            if isinstance(item, BaseException):
                raise item
            yield item

    thread = threading.Thread(target=make, name="imitate-render", daemon=True)
    thread.start()
    try:
        yield received()
    finally:
        stop.set()
        thread.join()


def interleaved(part: Callable[[slice], Iterator[T]], threads: int) -> Iterator[T]:
    """The items of a sequence, made by ``threads`` threads at once and yielded in order:
    thread ``k`` iterates ``part(slice(k, None, threads))``, the items ``k``, ``k + threads``,
    ... (each thread renders with a context of its own); one thread: ``part(slice(None))``,
    here. The items are one thread's when each depends on its index alone."""
    if threads <= 1:
        yield from part(slice(None))
        return
    with contextlib.ExitStack() as stack:
        parts = [
            stack.enter_context(in_thread(functools.partial(part, slice(k, None, threads)), 2))
            for k in range(threads)
        ]
        while True:
            for items in parts:
                item = next(items, _END)
                if item is _END:
                    return
                yield cast(T, item)  # not the sentinel _END


_END = object()  # the end of a thread's items
