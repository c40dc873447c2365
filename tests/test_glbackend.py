import pytest

from continuum_sim.glbackend import choose_gl_backend


def test_headless_defaults_to_egl():
    env: dict[str, str] = {}
    assert choose_gl_backend(env) == "egl"
    assert env["MUJOCO_GL"] == "egl" and env["PYOPENGL_PLATFORM"] == "egl"


def test_display_uses_glfw_and_explicit_choice_wins():
    assert choose_gl_backend({"DISPLAY": ":0"}) == "glfw"
    assert choose_gl_backend({"DISPLAY": ":0", "MUJOCO_GL": "EGL"}) == "egl"


def test_unknown_backend_is_rejected():
    with pytest.raises(ValueError, match="MUJOCO_GL: must be one of"):
        choose_gl_backend({"MUJOCO_GL": "vulkan"})
