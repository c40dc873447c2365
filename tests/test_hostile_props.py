"""Property tests: any input to the config and sweep-spec loaders or the numeric CLI arguments
yields a valid object or the one-line ``ConfigError`` (exit 2), never another exception."""

from __future__ import annotations

import copy
import os
import tempfile

from hypothesis import HealthCheck, given, settings
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
