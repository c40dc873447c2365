"""Property tests: any input to the config and sweep-spec loaders or the numeric CLI arguments
yields a valid object or the one-line ``ConfigError`` (exit 2), never another exception."""

from __future__ import annotations

import copy
import os
import tempfile

from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from continuum_sim.cli import main
from continuum_sim.configio import ConfigError, from_dict, load_toml, parse_toml_text, to_dict
from continuum_sim.geometry import ArmGeometry
from continuum_sim.scenario.config import ScenarioConfig
from continuum_sim.sweep.evaluations import KINDS
from continuum_sim.sweep.spec import MAX_VARIANTS, SweepSpec, _set_path, parse_spec

SETTINGS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
BASE = ScenarioConfig()
BASE_DICT = to_dict(BASE)


def _paths(node, prefix=""):
    """Every dotted path of the default scenario dict (tables, lists and leaves)."""
    out = [prefix] if prefix else []
    if isinstance(node, dict):
        for key, value in node.items():
            out += _paths(value, f"{prefix}.{key}" if prefix else key)
    elif isinstance(node, list):
        for i, value in enumerate(node):
            out += _paths(value, f"{prefix}.{i}")
    return out


PATHS = _paths(BASE_DICT)

keys = st.one_of(st.sampled_from(sorted({p.split(".")[-1] for p in PATHS})), st.text(max_size=12))
scalars = st.one_of(
    st.booleans(),
    st.integers(min_value=-(10**20), max_value=10**20),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=20),
)
values = st.recursive(scalars, lambda inner: st.lists(inner, max_size=4) | st.dictionaries(keys, inner, max_size=3),
                      max_leaves=8)



@SETTINGS
@given(st.lists(st.tuples(st.sampled_from(PATHS), values), min_size=1, max_size=3))
def test_scenario_loader_valid_or_config_error(edits):
    data = copy.deepcopy(BASE_DICT)
    for path, value in edits:
        try:
            _set_path(data, path, value)
        except (KeyError, IndexError, ValueError, TypeError):  # an earlier edit replaced a parent of this path
            continue
    try:
        config = from_dict(ScenarioConfig, data)
    except ConfigError as exc:
        assert "\n" not in str(exc) and len(str(exc)) < 2_000
        return
    from continuum_sim.limits import check_scenario

    try:
        check_scenario(config)
    except ConfigError:
        pass


@SETTINGS
@given(st.dictionaries(keys, values, max_size=4))
def test_arm_geometry_loader_valid_or_config_error(data):
    try:
        from_dict(ArmGeometry, data)
    except ConfigError as exc:
        assert "\n" not in str(exc)


@SETTINGS
@given(st.text(max_size=200))
def test_toml_text_parses_or_config_error(text):
    try:
        parse_toml_text(text, "x.toml")
    except ConfigError as exc:
        assert str(exc).startswith("x.toml: ")


@SETTINGS
@given(st.binary(max_size=300))
def test_toml_bytes_load_or_config_error(raw):
    fd, path = tempfile.mkstemp(suffix=".toml")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(raw)
        try:
            load_toml(path)
        except ConfigError as exc:
            assert str(exc).startswith(path)
    finally:
        os.unlink(path)


def _is_number_leaf(path: str) -> bool:
    node = BASE_DICT
    for part in path.split("."):
        node = node[int(part)] if isinstance(node, list) else node[part]
    return isinstance(node, (int, float)) and not isinstance(node, bool)


SWEEPABLE = [p for p in PATHS if _is_number_leaf(p)]
numbers = st.one_of(st.integers(min_value=-(10**6), max_value=10**6), st.floats(allow_nan=True, allow_infinity=True))
axis_values = st.one_of(
    st.lists(st.one_of(numbers, st.text(max_size=3), st.booleans()), max_size=4),
    st.fixed_dictionaries(
        {"start": numbers, "stop": numbers,
         "num": st.one_of(st.integers(min_value=-3, max_value=12), st.integers(MAX_VARIANTS + 1, 10 * MAX_VARIANTS))},
        optional={"scale": st.sampled_from(["linear", "log", "cubic"])},
    ),
    values,
)
evaluations = st.one_of(
    st.builds(lambda kind, extra: {"kind": kind, **extra}, st.sampled_from([*KINDS, "gravity", ""]),
              st.dictionaries(st.sampled_from(["q_deg", "settle_s", "stage", "force_n", "tool", "cables", "bogus"]),
                              values, max_size=2)),
    values,
)


@SETTINGS
@given(
    grid=st.one_of(st.dictionaries(st.one_of(st.sampled_from(SWEEPABLE), st.text(max_size=15)), axis_values, max_size=3),
                   values),
    evaluation=evaluations,
    metrics=st.one_of(st.none(), st.lists(st.one_of(st.sampled_from(["sag_mm", "deflection_mm"]), st.text(max_size=5)),
                                          max_size=3), values),
)
def test_sweep_spec_valid_or_config_error(grid, evaluation, metrics):
    data = {"grid": grid, "evaluation": evaluation}
    if metrics is not None:
        data["metrics"] = metrics
    try:
        spec = parse_spec(data)
    except ConfigError as exc:
        assert "\n" not in str(exc)
        return
    assert isinstance(spec, SweepSpec) and 1 <= spec.n_variants <= MAX_VARIANTS


cli_float = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.sampled_from(["nan", "-inf", "1e309", "0x10", "1_0", "", " ", "--", "1e-400", "٣"]),
)


def _check_cli(argv, allowed, capsys):
    code = main(argv)
    err = capsys.readouterr().err
    assert code in allowed, err
    assert "Traceback" not in err
    assert len([line for line in err.splitlines() if line.strip()]) <= 2  # ik: its verdict line (+ one warning line)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(q=st.lists(cli_float, min_size=0, max_size=8))
def test_fk_numeric_arguments(q, capsys):
    _check_cli(["fk", "--", *q] if q else ["fk"], (0, 2), capsys)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(position=st.lists(cli_float, min_size=3, max_size=3), k1=cli_float, tol=cli_float)
def test_ik_numeric_arguments(position, k1, tol, capsys):
    _check_cli(["ik", f"--k1={k1}", f"--tol={tol}", "--position", *position], (0, 1, 2), capsys)


def test_property_strategies_cover_real_fields():
    assert len(SWEEPABLE) > 50 and "model.stiffness_scale" in SWEEPABLE and "arm.sections.0.length" in SWEEPABLE


# ---------------------------------------------------------------- sweep check: per axis value, same verdict
def _exact_verdict(spec: SweepSpec) -> bool:
    """The oracle: every variant rebuilt whole from its dict and checked (what check_variants avoids)."""
    from continuum_sim.sweep.spec import _check_config, _variant_config

    for variant in spec.variants():
        try:
            _check_config(_variant_config(spec.base, BASE_DICT, variant.params), spec.evaluation)
        except ConfigError:
            return False
    return True


COMBINING = ["model.timestep", "control.rate_hz", "model.segments_per_section", "arm.disk_thickness",
             "arm.sections.0.length", "arm.sections.2.max_bend_deg", "model.stiffness_scale", "plan.cut_speed"]
FACTORS = (0.0, 0.005, 0.3, 1.0, 3.0, 40.0)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.dictionaries(st.sampled_from([p for p in COMBINING if p in SWEEPABLE]),
                       st.lists(st.sampled_from(FACTORS), min_size=1, max_size=3, unique=True), min_size=1, max_size=3),
       st.sampled_from(["gravity_sag", "scenario"]))
@example({"model.timestep": [1.0, 0.005], "control.rate_hz": [1.0, 0.3]}, "scenario")  # refused only as a pair
@example({"model.segments_per_section": [1.0, 2.0], "arm.disk_thickness": [1.0, 3.0]}, "gravity_sag")
def test_sweep_check_per_axis_value_gives_the_per_variant_verdict(factors, kind):
    from continuum_sim.sweep.spec import REBUILDS, check_variants

    grid = {}
    for path, fs in factors.items():
        base = _lookup_number(path)
        values = sorted({base * f if isinstance(base, float) else int(round(max(base, 10) * f)) for f in fs})
        grid[path] = values
    data = {"grid": grid, "evaluation": {"kind": kind}}
    try:
        spec = parse_spec(data)
    except ConfigError:
        spec = None
    if spec is None:  # refused: some variant must really be invalid (or a value alone)
        from continuum_sim.sweep import spec as spec_module

        original = spec_module.check_variants
        spec_module.check_variants = lambda *a, **k: None
        try:
            unchecked = parse_spec(data)
        except ConfigError:
            return  # a bad value alone, refused while parsing the axis
        finally:
            spec_module.check_variants = original
        assert not _exact_verdict(unchecked)
        return
    assert REBUILDS["count"] == 1 + sum(len(v) for v in grid.values())  # O(sum of axis sizes), not O(product)
    assert _exact_verdict(spec)
    check_variants(spec)
    variant = spec.variants()[-1]
    from continuum_sim.sweep.spec import apply_params

    assert spec.config_for(variant) == apply_params(spec.base, variant.params)  # the fast path builds the same config


def _lookup_number(path: str):
    node = BASE_DICT
    for part in path.split("."):
        node = node[int(part)] if isinstance(node, list) else node[part]
    return node


def test_maximum_grid_is_checked_with_rebuilds_per_axis_value_not_per_variant():
    """10^5 variants (the limit): 1 + 210 config rebuilds, the 10^4 same-part pairs re-made cheaply (was 10^5 rebuilds, 207 s)."""
    from continuum_sim.sweep.spec import REBUILDS

    spec = parse_spec({"grid": {"model.stiffness_scale": {"start": 0.5, "stop": 2.0, "num": 100},
                                "model.joint_damping": {"start": 0.1, "stop": 1.0, "num": 100},
                                "plan.cut_speed": {"start": 0.001, "stop": 0.002, "num": 10}},
                       "evaluation": {"kind": "gravity_sag"}})
    assert spec.n_variants == MAX_VARIANTS
    assert REBUILDS["count"] == 1 + 100 + 100 + 10


def test_sweep_groups_by_structural_values_as_structure_key_does():
    from continuum_sim.sweep.static import structural_paths, structure_key

    spec = parse_spec({"grid": {"model.stiffness_scale": [1.0, 2.0], "model.segments_per_section": [0, 10],
                                "control.rate_hz": [100.0, 125.0], "arm.sections.1.length": [0.1, 0.12]},
                       "evaluation": {"kind": "gravity_sag"}})
    structural = structural_paths(spec.paths)
    assert structural == ["model.segments_per_section", "arm.sections.1.length"]

    def partition(key):
        groups: dict = {}
        for v in spec.variants():
            groups.setdefault(key(v), []).append(v.index)
        return sorted(groups.values())

    assert partition(lambda v: tuple(v.param_dict[p] for p in structural)) == \
        partition(lambda v: structure_key(spec.config_for(v), spec.evaluation))


# ---------------------------------------------------------------- trajectory.npz: the configuration's bytes only
def _tiny_trajectory(wall_seconds: float, breakdown: dict[str, float]):
    import numpy as np

    from continuum_sim.scenario.trajectory import ArmTrajectory, Trajectory

    n, rng = 3, np.random.default_rng(0)
    arm = ArmTrajectory(q_plan=rng.random((n, 6)), q_cmd=rng.random((n, 6)), tcp_plan=rng.random((n, 4, 4)),
                        tcp_pos=rng.random((n, 3)), tcp_mat=rng.random((n, 3, 3)), cable_length=rng.random((n, 9)),
                        cable_tension=rng.random((n, 9)), cable_anchor_ratio=np.ones((n, 9)),
                        cable_common_mode=rng.random((n, 3)), disk_pos=rng.random((n, 4, 3)))
    return Trajectory(t=np.arange(n) * 0.01, stage=np.zeros(n, np.int64), plan_index=np.arange(n), sample_pos=rng.random((n, 3)),
                      sample_rel_pos=rng.random((n, 3)), sample_welded=np.ones(n, bool), cells_remaining=np.full(n, 5),
                      spindle_speed=rng.random(n), contact_force=rng.random((n, 4)), arm_distance=rng.random(n),
                      arms={"left": arm, "right": arm}, stage_names=("initial",), tool_arm={"grinder": "left"},
                      cell_removal_times=np.array([0.01, np.nan]), detach_time=None, stages_run=("initial",), failure=None,
                      wall_breakdown_s=breakdown, wall_seconds=wall_seconds)


@settings(max_examples=20, deadline=None)
@given(st.floats(0.0, 1e6), st.dictionaries(st.sampled_from(["setup", "physics", "control"]), st.floats(0.0, 1e3)),
       st.integers(0, 2**31))
def test_trajectory_bytes_hold_no_wall_clock(wall, breakdown, clock):
    import time
    from unittest import mock

    reference = _tiny_trajectory(1.0, {}).to_bytes()
    with mock.patch.object(time, "localtime", return_value=time.gmtime(clock)), mock.patch.object(time, "time", return_value=clock):
        again = _tiny_trajectory(wall, breakdown).to_bytes()  # another run: other wall figures, another date
    assert again == reference


def test_trajectory_without_wall_keys_loads_and_old_files_still_do(tmp_path):
    import json

    import numpy as np

    from continuum_sim.scenario.trajectory import Trajectory

    path = tmp_path / "trajectory.npz"
    _tiny_trajectory(5.0, {"physics": 4.0}).save(path)
    with np.load(path) as npz:
        meta = json.loads(str(npz["meta"]))
    assert not {"wall_seconds", "wall_breakdown_s"} & set(meta)
    loaded = Trajectory.load(path)
    assert loaded.wall_seconds is None and loaded.wall_breakdown_s == {}
    assert loaded.to_bytes() == path.read_bytes()
    old = {key: np.load(path)[key] for key in np.load(path).files}  # a file from before: wall figures in meta
    old["meta"] = np.array(json.dumps({**meta, "wall_seconds": 5.0, "wall_breakdown_s": {"physics": 4.0}}))
    np.savez_compressed(tmp_path / "old.npz", **old)
    assert Trajectory.load(tmp_path / "old.npz").wall_seconds == 5.0
