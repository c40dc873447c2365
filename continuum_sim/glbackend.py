"""MuJoCo's OpenGL backend: chosen only by what renders, before ``mujoco``/``dm_control`` load it.

MuJoCo, dm_control and PyOpenGL read ``MUJOCO_GL``/``PYOPENGL_PLATFORM`` once, at import
time, and ``import mujoco`` (or dm_control's ``mjcf``) then loads that backend's library:
with ``MUJOCO_GL=osmesa`` and no OSMesa installed, even building a model failed. So:

* commands that render nothing run with ``MUJOCO_GL=disable`` (``disable_gl``): no GL
  library is ever loaded, whatever the machine has;
* commands that render (``run --video``, ``view``) check the chosen backend's library
  first (``require_gl_backend``) and are refused in one line naming the backend and how
  to install it.

Headless machines (no ``DISPLAY``) get EGL, which works both on Mesa (CPU) and on NVIDIA
GPUs; a user's explicit ``MUJOCO_GL`` always wins.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import sys
from collections.abc import MutableMapping

VALID_BACKENDS = ("egl", "osmesa", "glfw", "disable")

# backend -> (library name, shared objects tried, how to install it)
_LIBRARIES = {
    "egl": ("EGL", ("libEGL.so.1", "libEGL.so"), "apt-get install libegl1, or an NVIDIA driver"),
    "osmesa": ("OSMesa", ("libOSMesa.so.8", "libOSMesa.so.6", "libOSMesa.so"), "apt-get install libosmesa6"),
}


class GLBackendError(ValueError):
    """The GL backend a rendering command needs is unusable (message: one line, names the backend and the fix)."""


def choose_gl_backend(environ: MutableMapping[str, str] | None = None) -> str:
    """Pick and export the GL backend; returns it. Raises ValueError for an unknown one."""
    env = os.environ if environ is None else environ
    requested = env.get("MUJOCO_GL", "").strip().lower()
    if requested:
        if requested not in VALID_BACKENDS:
            raise ValueError(f"MUJOCO_GL: must be one of {', '.join(VALID_BACKENDS)} (got {requested!r})")
        backend = requested
    elif env.get("DISPLAY") or env.get("WAYLAND_DISPLAY"):
        backend = "glfw"
    else:
        backend = "egl"
    env["MUJOCO_GL"] = backend
    if backend in ("egl", "osmesa"):
        env.setdefault("PYOPENGL_PLATFORM", backend)
    return backend


def library_found(backend: str) -> bool:
    """Whether the backend's GL library can be loaded here (glfw: the ``glfw`` package finds its own)."""
    if backend == "glfw":
        try:
            import glfw  # noqa: F401 - the wheel ships libglfw; ImportError when it cannot load it
        except (ImportError, OSError):
            return False
        return True
    if backend not in _LIBRARIES or not sys.platform.startswith("linux"):
        return True  # macOS/Windows: MuJoCo uses the system's GL
    name, files, _ = _LIBRARIES[backend]
    found = ctypes.util.find_library(name)
    for candidate in (*files, *([found] if found else [])):
        try:
            ctypes.CDLL(candidate)
        except OSError:
            continue
        return True
    return False


def require_gl_backend(environ: MutableMapping[str, str] | None = None) -> str:
    """For a command that renders: choose the backend and check it can load; ``GLBackendError`` if not."""
    backend = choose_gl_backend(environ)
    if backend == "disable":
        raise GLBackendError("MUJOCO_GL=disable: rendering is switched off; unset MUJOCO_GL or set it to egl or osmesa")
    if library_found(backend):
        return backend
    others = [b for b in ("egl", "osmesa") if b != backend and library_found(b)]
    alternative = f" — or use MUJOCO_GL={others[0]}" if others else ""
    if backend == "glfw":
        raise GLBackendError(f"MUJOCO_GL=glfw: GLFW not found (pip install glfw; it needs a display){alternative}")
    name, _, install = _LIBRARIES[backend]
    raise GLBackendError(f"MUJOCO_GL={backend}: {name} not found ({install}){alternative}")


def disable_gl(environ: MutableMapping[str, str] | None = None) -> None:
    """For a command that renders nothing: no GL library is loaded by ``import mujoco``/dm_control."""
    env = os.environ if environ is None else environ
    env["MUJOCO_GL"] = "disable"
