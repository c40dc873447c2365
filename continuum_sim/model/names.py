"""Names of the generated model's elements: the one place the builders' naming is spelled out.

The builders (``arm``, ``backbone``, ``tools``, ``scene``) name elements with these
helpers or the constants they re-export; the runtime reaches the compiled model only through
``model.handles.SceneHandles``, which is built from these names. No other module writes a
model element name (``tests/test_scene_contract.py`` greps for it). Light: imports nothing
from MuJoCo.
"""

from __future__ import annotations

SEPARATOR = "/"  # dm_control's attach() prefixes every name with the attached model's name and "/"

TCP_SITE = "tcp"  # tool-centre point site of an arm (on the last disk, tool length along its z)
TOOL_MOUNT_SITE = "tool_mount"  # tip frame of an arm, where its tool attaches
BASE_BODY = "base"
SINGLE_ARM = "arm"  # the arm's name in the standalone arm model (``arm.build_single_arm_model``)


def scoped(*parts: str) -> str:
    """``left`` + ``grinder`` + ``cutter`` -> ``left/grinder/cutter`` (names after attachment)."""
    return SEPARATOR.join(parts)


def cable(section: int, index: int) -> str:
    """A cable's tendon and actuator name inside its arm: ``cable_<section>_<index>`` (3 per section)."""
    return f"cable_{section}_{index}"


def disk(index: int) -> str:
    """A disk body (and its geom) inside its arm, 1-based from the base: ``disk_<i>``."""
    return f"disk_{index}"


def joint(index: int, axis: str | None = None) -> str:
    """The joint carrying disk ``index``: ``joint_<i>`` (ball) or ``joint_<i>_<axis>`` (hinges)."""
    return f"joint_{index}" if axis is None else f"joint_{index}_{axis}"


def hole_site(disk_index: int, cable_index: int) -> str:
    """The site where cable ``cable_index`` passes disk ``disk_index`` (0 = base)."""
    return f"hole_{disk_index}_{cable_index}"


def arm_cable_names(arm: str, n_sections: int) -> list[str]:
    """Every cable of ``arm`` in model order (section by section, three each), scoped."""
    return [scoped(arm, cable(k, c)) for k in range(n_sections) for c in range(3)]
