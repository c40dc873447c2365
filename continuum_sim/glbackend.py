"""Choose MuJoCo's OpenGL backend before ``mujoco`` or ``dm_control`` is imported.

MuJoCo and PyOpenGL read ``MUJOCO_GL``/``PYOPENGL_PLATFORM`` once, at import time, so
the choice has to happen first. Headless machines (no ``DISPLAY``) get EGL, which works
both on Mesa (CPU) and on NVIDIA GPUs; a user's explicit ``MUJOCO_GL`` always wins.
"""

from __future__ import annotations

import os
from collections.abc import MutableMapping

VALID_BACKENDS = ("egl", "osmesa", "glfw", "disable")


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

