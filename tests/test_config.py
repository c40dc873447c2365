"""Arm configuration: defaults, TOML round trip, and one clear error per bad value."""

import dataclasses
import subprocess
import sys

import pytest

from continuum_sim import ArmGeometry, ConfigError, SectionGeometry
from continuum_sim.configio import dumps_toml, from_dict, get_path, replace_path, to_dict


def test_defaults_follow_spec(geometry):
    lengths = [s.length for s in geometry.sections]
    assert lengths == [0.210, 0.180, 0.150]
    assert [s.disk_diameter for s in geometry.sections] == [0.046, 0.043, 0.040]
    assert [s.hinge_width for s in geometry.sections] == [0.006, 0.005, 0.004]
    assert [s.hinge_thickness for s in geometry.sections] == [0.001] * 3
    assert [s.n_segments for s in geometry.sections] == [10] * 3
    assert geometry.length == pytest.approx(0.540)
    assert geometry.cable_hole_radius == 0.015
    assert [s.cable_angles_deg for s in geometry.sections] == [(0, 120, 240), (40, 160, 280), (80, 200, 320)]
    assert geometry.material.youngs_modulus == 2.0e9 and geometry.material.poisson_ratio == 0.38
    assert geometry.tools.grinder_length == 0.060 and geometry.tools.gripper_length == 0.070
    assert geometry.cable_names("left")[4] == "left/cable_1_1"


def test_toml_round_trip(tmp_path, geometry):
    changed = replace_path(geometry, "sections.1.n_segments", 7)
    path = tmp_path / "arm.toml"
    changed.save_toml(path)
    loaded = ArmGeometry.from_toml(path)
    assert loaded == changed
    assert loaded.sections[1].n_segments == 7
    assert get_path(loaded, "sections.1.n_segments") == 7


@pytest.mark.parametrize(
    "path, value, field, fragment",
    [
        ("sections.0.length", -0.1, "sections[0].length", "0 < length"),
        ("sections.2.length", 0.0, "sections[2].length", "0 < length"),
        ("sections.1.n_segments", 0, "sections[1].n_segments", "1 <= n_segments"),
        ("sections.1.n_segments", 2.5, "sections[1].n_segments", "integer"),
        ("cable_hole_radius", 0.025, "cable_hole_radius", "smallest disk radius"),
        ("sections.0.disk_diameter", "wide", "sections[0].disk_diameter", "must be a number"),
        ("material.poisson_ratio", 0.7, "material.poisson_ratio", "poisson_ratio < 0.5"),
        ("sections.0.max_bend_deg", 200.0, "sections[0].max_bend_deg", "max_bend_deg <= 180"),
        ("sections.0.cable_angles_deg", [0, 5, 240], "sections[0].cable_angles_deg", "10 deg apart"),
        ("disk_thickness", 0.05, "disk_thickness", "segment pitch"),
    ],
)
def test_bad_values_name_the_field_and_range(geometry, path, value, field, fragment):
    with pytest.raises(ConfigError) as info:
        replace_path(geometry, path, value)
    assert info.value.field == field
    assert fragment in str(info.value)
    assert "\n" not in str(info.value)


def test_unknown_key_lists_allowed_keys(geometry):
    data = to_dict(geometry)
    data["sections"][0]["colour"] = "red"
    with pytest.raises(ConfigError, match=r"sections\[0\]\.colour: unknown key; allowed keys are length"):
        from_dict(ArmGeometry, data)


def test_direct_construction_validates():
    with pytest.raises(ConfigError, match="hinge_thickness: must satisfy 0 < hinge_thickness"):
        SectionGeometry(0.2, 0.04, 0.004, -0.001)
    with pytest.raises(dataclasses.FrozenInstanceError):
        ArmGeometry.default().disk_thickness = 1.0  # type: ignore[misc]


def test_toml_writer_output_is_valid_toml(geometry):
    import tomllib

    assert tomllib.loads(dumps_toml(to_dict(geometry))) == to_dict(geometry) | {
        "sections": [to_dict(s) | {"cable_angles_deg": list(s.cable_angles_deg)} for s in geometry.sections]
    }


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "continuum_sim", *args], capture_output=True, text=True)


def test_cli_fk_prints_tip(tmp_path):
    result = _cli("fk", "0", "0", "0", "0", "0", "0", "--json")
    assert result.returncode == 0, result.stderr
    import json

    tip = json.loads(result.stdout)["tip_position_m"]
    assert tip == pytest.approx([0.0, 0.0, 0.54], abs=1e-12)


@pytest.mark.parametrize(
    "toml_text, fragment",
    [
        ("cable_hole_radius = -1.0\n", "cable_hole_radius"),
        ("[[sections]]\nlength = 0.2\ndisk_diameter = 0.04\nhinge_width = 0.004\nhinge_thickness = 0.001\nn_segments = 0\n", "n_segments"),
        ("bogus = 3\n", "bogus: unknown key"),
        ("this is not toml", "invalid TOML"),
    ],
)
def test_cli_bad_config_is_one_line_and_exit_2(tmp_path, toml_text, fragment):
    path = tmp_path / "arm.toml"
    path.write_text(toml_text)
    result = _cli("fk", "0", "0", "0", "0", "0", "0", "--config", str(path))
    assert result.returncode == 2
    assert fragment in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1, result.stderr
    assert "Traceback" not in result.stderr


def test_cli_rejects_out_of_range_bend():
    result = _cli("fk", "120", "0", "0", "0", "0", "0", "--deg")
    assert result.returncode == 2
    assert "θ0 must satisfy 0 <= θ0 <= 90 deg" in result.stderr


@pytest.mark.parametrize("command", [["fk", "0", "0", "0", "0", "0", "0", "--config"], ["plan", "--layout"], ["run", "--config"]])
def test_cli_missing_config_file_is_named_once(tmp_path, command):
    missing = str(tmp_path / "missing.toml")
    result = _cli(*command, missing)
    assert result.returncode == 2
    assert result.stderr.count(missing) == 1 and "file not found" in result.stderr


def test_require_int_names_the_field_and_the_range():
    from continuum_sim.configio import require_int

    require_int("a.n", 3, 1, 5)
    with pytest.raises(ConfigError, match=r"^a\.n: must be an integer \(got True\)$"):
        require_int("a.n", True, 1, 5)
    with pytest.raises(ConfigError, match=r"^a\.n: must be an integer \(got 2\.5\)$"):
        require_int("a.n", 2.5, 1, 5)
    with pytest.raises(ConfigError, match=r"^a\.n: must satisfy 1 <= n <= 5 \(got 6\)$"):
        require_int("a.n", 6, 1, 5)
    with pytest.raises(ConfigError, match=r"^seed: must satisfy 0 <= seed, any int \(got -1\)$"):
        require_int("seed", -1, 0, hint=", any int")
