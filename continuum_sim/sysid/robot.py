"""An OpenCR generation JSON (a robot description) as a scenario TOML for replay/identify.

Mapping (facts from OpenCR-MuJoCo's ``configs/generation/README.md`` and its generator,
ContinuumRoboticsLab/opencr-mujoco @ 17fff8b: tendon angle = seg_offset + i·2π/M +
delta_i in the robot frame; ``tendon_kp_array`` per tendon overrides ``tendon_kp``; the
``inverse_length`` multiplier runs from ``tendon_kp_scale_factor`` at the base segment to
1 at the tip). Every field is listed as mapped, assumed or not mapped in the TOML's
header and in docs/sysid.md; a value that cannot be represented is one ``ConfigError``.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from ..configio import ConfigError, dumps_toml

TENDONS = 3

# Values the JSON does not give, with why they are what they are (all *assumed*).
ASSUMED: dict[str, tuple[Any, str]] = {
    "arm.disk_thickness": (0.002, "no disk thickness in the JSON; sets only the disk mass (gravity-off replays ignore it)"),
    "arm.sections.*.hinge_width": (0.001, "unused with the rod backbone (kept small and valid)"),
    "arm.sections.*.hinge_thickness": (0.0005, "unused with the rod backbone (kept small and valid)"),
    "arm.sections.*.max_bend_deg": (120.0, "no bend limit in the JSON (used by planning only)"),
    "model.timestep": (0.002, "numerical: quasi-static settling"),
    "model.cable_damping": (5.0, "numerical (N s/m): settling of the servo loop"),
    "layout.left.position": ([0.0, 0.0, 0.0], "the robot's base at the recording frame's origin (import-recording's frame)"),
}
NOT_MAPPED = {
    "description": "a name (kept as a comment)",
    "mass": "used by upstream's 'direct' joint mode only",
    "joint_range": "joints unlimited, as upstream's default",
    "vert_joint_range": "joints unlimited, as upstream's default",
    "gravity": "a property of the recording (its `gravity` metadata; import-recording writes false)",
    "plane": "no floor in a replay",
    "plane_style": "visual",
    "disable_self_collision": "a replay has no self collision",
    "mounting": "the Franka mount; the recording frame puts the base at the origin",
    "actuator_type": "superseded by actuator_properties.tendon_actuator_type",
    "actuator_properties.tendon_ctrlrange": "the replay's cable controls are unbounded within +-0.15 m",
    "actuator_properties.tendon_constraint_factor": "no counterpart",
    "actuator_properties.tendon_forcelimited": "cables only pull in this model (always force-limited)",
    "joint_deadband": "no counterpart (0 in the shipped robots)",
}


def _get(data: dict[str, Any], key: str, where: str) -> Any:
    if key not in data:
        raise ConfigError(where, f"missing field {key!r}")
    return data[key]


def _per_segment(value: Any, n: int, key: str) -> list[float]:
    if isinstance(value, dict):
        try:
            return [float(value[str(k + 1)]) for k in range(n)]
        except KeyError as exc:
            raise ConfigError(key, f"needs entries '1'..'{n}' (missing {exc})") from None
    if isinstance(value, list) and len(value) == n:
        return [float(v) for v in value]
    raise ConfigError(key, f"must give one value per segment ({n})")


def convert(data: dict[str, Any], name: str = "robot") -> tuple[dict[str, Any], list[str]]:
    """(scenario TOML dict, header lines listing every mapped/assumed/unmapped field)."""
    mapped: list[str] = []
    n = int(_get(data, "num_segments", name))
    if not 1 <= n <= 10:
        raise ConfigError("num_segments", f"must be 1..10 (got {n})")
    lengths = _per_segment(_get(data, "segment_lengths", name), n, "segment_lengths")
    links = [int(v) for v in _per_segment(_get(data, "links_per_segment", name), n, "links_per_segment")]
    mapped += ["segment_lengths -> arm.sections.*.length (m)", "links_per_segment -> arm.sections.*.n_segments"]
    radius = float(_get(data, "radius", name))
    mapped.append("radius -> arm.sections.*.disk_diameter = 2 x radius (upstream: the visual link radius)")
    mat = _get(data, "material_properties", name)
    if float(mat.get("inner_radius", 0.0)) != 0.0:
        raise ConfigError("material_properties.inner_radius", "a hollow backbone is not modelled (the rod is solid); must be 0")
    mapped += ["material_properties.outer_radius/youngs_modulus/poisson_ratio/density -> arm.rod.*",
               "material_properties.damping -> model.joint_damping (N m s/rad per joint)"]
    jpl = int(data.get("joints_per_link", 2))
    if jpl not in (2, 3):
        raise ConfigError("joints_per_link", f"must be 2 or 3 (got {jpl})")
    mapped.append("joints_per_link 2/3 -> model.joint hinge_pair/hinge_triple (arm.central_joint universal/ball)")
    if data.get("actuation_mode", "parallel_tendons") != "parallel_tendons":
        raise ConfigError("actuation_mode", f"only 'parallel_tendons' robots are tendon-driven (got {data.get('actuation_mode')!r})")
    segs = _get(_get(data, "actuation_details", name), "segments", "actuation_details")
    if len(segs) != n:
        raise ConfigError("actuation_details.segments", f"must have {n} entries (got {len(segs)})")
    for k, seg in enumerate(segs):
        if int(seg.get("number_of_tendons", 0)) != TENDONS:
            raise ConfigError(f"actuation_details.segments[{k}].number_of_tendons",
                              f"the model drives every section with 3 tendons (got {seg.get('number_of_tendons')})")
    hole = [float(seg["distance_to_backbone"]) for seg in segs]
    mapped.append("actuation_details.segments[*].distance_to_backbone -> arm.sections.*.cable_hole_radius (arm.cable_hole_radius: the largest)")
    props = _get(data, "actuator_properties", name)
    if props.get("tendon_actuator_type", "position") != "position":
        raise ConfigError("actuator_properties.tendon_actuator_type", "only position (length-controlled) tendons replay here")
    kp = float(_get(props, "tendon_kp", "actuator_properties"))
    kp_tendon = _tendon_gains(props, n, kp)
    mapped.append("tendon_kp -> model.cable_kp; tendon_kp_array (per tendon, overrides) / inverse_length scaling -> "
                  "arm.sections.*.cable_gain_scale (section mean / cable_kp)")
    pre = np.asarray(props.get("tendon_pretension", [0.0] * (n * TENDONS)), dtype=float)
    if pre.shape != (n * TENDONS,):
        raise ConfigError("actuator_properties.tendon_pretension", f"must have {n * TENDONS} entries (got {pre.size})")
    mapped.append("tendon_pretension -> control.pretension (the smallest) + arm.sections.*.extra_pretension (section mean above it)")
    force = props.get("tendon_forcerange", "-100 0")
    fmax = abs(float(str(force).split()[0]))
    mapped.append("tendon_forcerange -> model.cable_max_force")
    offsets = np.asarray(data.get("seg_offsets", [0.0] * n), dtype=float)
    deltas = np.asarray(data.get("tendon_angle_deltas") or np.zeros((n, TENDONS)), dtype=float)
    if offsets.shape != (n,) or deltas.shape != (n, TENDONS):
        raise ConfigError("seg_offsets", f"seg_offsets needs {n} values and tendon_angle_deltas {n}x3")
    mapped.append("seg_offsets + i*120 deg + tendon_angle_deltas -> arm.sections.*.cable_angles_deg (robot frame, deg)")

    sections = []
    kp_sec = kp_tendon.reshape(n, TENDONS)
    pre_sec = pre.reshape(n, TENDONS)
    base_pre = float(pre.min())
    a = ASSUMED
    uniform_hole = len(set(hole)) == 1
    for k in range(n):
        angles = [_wrap(math.degrees(offsets[k] + i * 2 * math.pi / TENDONS + deltas[k, i])) for i in range(TENDONS)]
        sec: dict[str, Any] = {
            "length": lengths[k], "disk_diameter": 2.0 * radius, "hinge_width": a["arm.sections.*.hinge_width"][0],
            "hinge_thickness": a["arm.sections.*.hinge_thickness"][0], "n_segments": links[k],
            "cable_angles_deg": [round(x, 4) for x in angles], "max_bend_deg": a["arm.sections.*.max_bend_deg"][0],
            "cable_gain_scale": float(kp_sec[k].mean() / kp),
            "extra_pretension": float(pre_sec[k].mean() - base_pre),
            "cable_hole_radius": hole[k],  # per section, so it can be fitted per section
        }
        sections.append(sec)
    spread = [k for k in range(n) if np.ptp(kp_sec[k]) > 1e-9 * kp or np.ptp(pre_sec[k]) > 1e-9]
    notes = [f"section {k}: tendons differ in kp or pretension; the section mean is used" for k in spread]
    config = {
        "arm": {
            "backbone": "rod", "central_joint": "universal" if jpl == 2 else "ball",
            "cable_hole_radius": hole[0] if uniform_hole else max(hole),
            "disk_thickness": a["arm.disk_thickness"][0],
            "rod": {"radius": float(mat["outer_radius"]), "youngs_modulus": float(mat["youngs_modulus"]),
                    "poisson_ratio": float(mat.get("poisson_ratio", 0.3)), "density": float(mat.get("density", 6450.0))},
            "sections": sections,
        },
        "model": {"joint": "hinge_pair" if jpl == 2 else "hinge_triple", "cable_model": "lumped", "cable_kp": kp,
                  "cable_max_force": fmax, "cable_damping": a["model.cable_damping"][0],
                  "joint_damping": float(mat.get("damping", 0.05)), "timestep": a["model.timestep"][0]},
        "control": {"pretension": base_pre},
        "layout": {"left": {"position": a["layout.left.position"][0]}},
    }
    header = [f"Robot {data.get('description', name)!r} from its OpenCR generation JSON ({name}),",
              "converted by `continuum-sim import-robot` (docs/sysid.md). Fields:",
              *(f"  mapped: {m}" for m in mapped),
              *(f"  ASSUMED {k} = {v[0]}: {v[1]}" for k, v in a.items()),
              *(f"  not mapped: {k} ({why})" for k, why in NOT_MAPPED.items() if why and k in data),
              *(f"  note: {x}" for x in notes),
              "  unknown JSON keys: " + (", ".join(sorted(set(data) - _KNOWN)) or "none"),
              "Tendon angles are in the robot frame; the recording's frame may be turned: identify "
              "--calibrate-angles measures them from the tendon-pull rows."]
    return config, header


_KNOWN = {"num_segments", "segment_lengths", "links_per_segment", "radius", "material_properties", "joints_per_link",
          "joint_config_mode", "actuation_mode", "actuation_details", "actuator_properties", "seg_offsets",
          "tendon_angle_deltas", *NOT_MAPPED}


def _wrap(deg: float) -> float:
    return (deg + 180.0) % 360.0 - 180.0


def _tendon_gains(props: dict[str, Any], n: int, kp: float) -> np.ndarray:
    array = props.get("tendon_kp_array")
    if isinstance(array, list) and array:
        if len(array) != n * TENDONS:
            raise ConfigError("actuator_properties.tendon_kp_array", f"must have {n * TENDONS} entries (got {len(array)})")
        return np.asarray(array, dtype=float)
    mult = np.ones(n)
    if props.get("tendon_kp_scaling", "none") == "inverse_length" and n > 1:
        f = float(props.get("tendon_kp_scale_factor", 1.0))
        mult = 1.0 + (f - 1.0) * (n - 1 - np.arange(n)) / (n - 1)
    return np.repeat(kp * mult, TENDONS)


def import_robot(path: str | os.PathLike[str]) -> tuple[str, dict[str, Any]]:
    """(TOML text, the config dict) of the generation JSON at ``path``; checked by loading it."""
    from ..scenario.config import ScenarioConfig, merged

    where = str(path)
    try:
        data = json.loads(Path(path).read_text())
    except OSError as exc:
        raise ConfigError(where, f"cannot read ({exc.strerror or exc})") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ConfigError(where, f"not a JSON file ({exc})") from None
    if not isinstance(data, dict):
        raise ConfigError(where, "must be a JSON object (an OpenCR generation config)")
    try:
        config, header = convert(data, Path(path).name)
    except (KeyError, TypeError, ValueError) as exc:
        raise ConfigError(where, f"unreadable field ({exc})") from None
    except ConfigError as exc:
        raise exc.under(f"{where}: ") from None
    try:
        merged(ScenarioConfig.default(), config)
    except ConfigError as exc:
        raise exc.under(f"{where} as a scenario: ") from None
    text = "".join(f"# {h}\n" for h in header) + "\n" + dumps_toml(config)
    return text, config
