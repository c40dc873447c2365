"""Strict conversion between frozen dataclass configs, plain dicts and TOML.

One generic layer serves every config in the package (arm geometry, model options,
scenario, sweep specs): unknown keys, wrong types and out-of-range values all become a
``ConfigError`` that names the dotted field path, so the CLI can print one line and exit 2.
"""

from __future__ import annotations

import dataclasses
import math
import os
import tempfile
import tomllib
import types
from collections.abc import Callable
from pathlib import Path
from typing import Any, Literal, TypeVar, Union, get_args, get_origin, get_type_hints

T = TypeVar("T")


class ConfigError(ValueError):
    """A configuration value is invalid; ``field`` is its dotted path."""

    def __init__(self, field: str, message: str) -> None:
        self.field = field
        self.message = message
        super().__init__(f"{field}: {message}")

    def under(self, prefix: str) -> "ConfigError":
        """The same error with its field path prefixed by the parent's path."""
        if not prefix:
            return self
        joiner = "" if self.field.startswith("[") or prefix.endswith(" ") else "."
        return ConfigError(f"{prefix}{joiner}{self.field}", self.message)


# --------------------------------------------------------------------------- checks
def require_finite(field: str, value: float) -> None:
    if not math.isfinite(value):
        raise ConfigError(field, f"must be a finite number (got {value!r})")


def require_range(
    field: str,
    value: float,
    low: float | None = None,
    high: float | None = None,
    *,
    low_inclusive: bool = False,
    high_inclusive: bool = True,
) -> None:
    """Raise unless ``low <(=) value <(=) high``; the message states the allowed range."""
    require_finite(field, value)
    ok = True
    if low is not None:
        ok &= value >= low if low_inclusive else value > low
    if high is not None:
        ok &= value <= high if high_inclusive else value < high
    if not ok:
        lo = "" if low is None else f"{low:g} {'<=' if low_inclusive else '<'} "
        hi = "" if high is None else f" {'<=' if high_inclusive else '<'} {high:g}"
        raise ConfigError(field, f"must satisfy {lo}{field.split('.')[-1]}{hi} (got {value!r})")


def require_positive(field: str, value: float) -> None:
    require_range(field, value, 0.0)


def require_solref(field: str, value: tuple[float, ...]) -> None:
    """MuJoCo ``solref`` in its standard form: (time constant > 0, damping ratio > 0)."""
    if len(value) != 2:
        raise ConfigError(field, f"must have 2 entries (time constant, damping ratio) (got {len(value)})")
    require_positive(f"{field}[0]", value[0])
    require_positive(f"{field}[1]", value[1])


def require_solimp(field: str, value: tuple[float, ...]) -> None:
    """MuJoCo ``solimp`` (d0, dwidth, width): impedances 0 < d0 <= dwidth < 1, width > 0."""
    if len(value) != 3:
        raise ConfigError(field, f"must have 3 entries (d0, dwidth, width) (got {len(value)})")
    require_range(f"{field}[0]", value[0], 0.0, 1.0, high_inclusive=False)
    require_range(f"{field}[1]", value[1], value[0], 1.0, low_inclusive=True, high_inclusive=False)
    require_positive(f"{field}[2]", value[2])


def require_int(field: str, value: object, low: int, high: int | None = None, hint: str = "") -> None:
    """Raise unless ``value`` is an int (a bool is not) with ``low <= value (<= high)``.

    ``hint`` is appended to the range, e.g. what the lower bound means.
    """
    if isinstance(value, bool) or not isinstance(value, int):
        raise ConfigError(field, f"must be an integer (got {value!r})")
    if value < low or (high is not None and value > high):
        name = field.split(".")[-1]
        bound = f"{low} <= {name}" + ("" if high is None else f" <= {high}")
        raise ConfigError(field, f"must satisfy {bound}{hint} (got {value})")


# ------------------------------------------------------------------ dict <-> dataclass
def to_dict(config: Any) -> Any:
    """A dataclass tree as nested dicts/lists of plain scalars (TOML-ready)."""
    if dataclasses.is_dataclass(config) and not isinstance(config, type):
        return {f.name: to_dict(getattr(config, f.name)) for f in dataclasses.fields(config)}
    if isinstance(config, (tuple, list)):
        return [to_dict(v) for v in config]
    return config


def _type_name(tp: Any) -> str:
    origin = get_origin(tp)
    if origin is Literal:
        return "one of " + ", ".join(repr(a) for a in get_args(tp))
    if origin in (tuple, list):
        return "a list"
    if dataclasses.is_dataclass(tp):
        return "a table"
    return getattr(tp, "__name__", str(tp))


def _convert(tp: Any, value: Any, field: str) -> Any:
    origin = get_origin(tp)
    if origin in (Union, types.UnionType):
        options = get_args(tp)
        if value is None and type(None) in options:
            return None
        errors = []
        for option in options:
            if option is type(None):
                continue
            try:
                return _convert(option, value, field)
            except ConfigError as exc:
                errors.append(exc)
        raise errors[0]
    if origin is Literal:
        if value not in get_args(tp):
            raise ConfigError(field, f"must be {_type_name(tp)} (got {value!r})")
        return value
    if dataclasses.is_dataclass(tp):
        if isinstance(value, tp):
            return value
        if not isinstance(value, dict):
            raise ConfigError(field, f"must be a table (got {type(value).__name__})")
        return from_dict(tp, value, prefix=field)
    if origin is tuple:
        if not isinstance(value, (list, tuple)):
            raise ConfigError(field, f"must be a list (got {type(value).__name__})")
        args = get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(args[0], v, f"{field}[{i}]") for i, v in enumerate(value))
        if len(args) != len(value):
            raise ConfigError(field, f"must have exactly {len(args)} entries (got {len(value)})")
        return tuple(_convert(a, v, f"{field}[{i}]") for i, (a, v) in enumerate(zip(args, value)))
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(field, f"must be a number (got {type(value).__name__} {value!r})")
        value = float(value)
        require_finite(field, value)
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            if isinstance(value, float) and value.is_integer():
                return int(value)
            raise ConfigError(field, f"must be an integer (got {type(value).__name__} {value!r})")
        return value
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(field, f"must be true or false (got {value!r})")
        return value
    if tp is str:
        if not isinstance(value, str):
            raise ConfigError(field, f"must be a string (got {type(value).__name__})")
        return value
    if tp is Any:
        return value
    raise TypeError(f"unsupported config type {tp!r} for {field}")


def from_dict(cls: type[T], data: dict[str, Any], prefix: str = "") -> T:
    """Build dataclass ``cls`` from ``data``; missing keys take defaults, unknown keys fail."""
    if not isinstance(data, dict):
        raise ConfigError(prefix or cls.__name__, f"must be a table (got {type(data).__name__})")
    hints = get_type_hints(cls)
    names = [f.name for f in dataclasses.fields(cls) if f.init]
    for key in data:
        if key not in names:
            where = f"{prefix}.{key}" if prefix else key
            raise ConfigError(where, f"unknown key; allowed keys are {', '.join(names)}")
    kwargs = {}
    for name in names:
        if name in data:
            where = f"{prefix}.{name}" if prefix else name
            kwargs[name] = _convert(hints[name], data[name], where)
    try:
        return cls(**kwargs)
    except ConfigError as exc:
        raise exc.under(prefix) from None


def replace_path(config: T, path: str, value: Any) -> T:
    """A copy of ``config`` with the field at dotted ``path`` (``sections.0.length``) set."""
    data = to_dict(config)
    node: Any = data
    parts = path.split(".")
    for i, part in enumerate(parts):
        last = i == len(parts) - 1
        where = ".".join(parts[: i + 1])
        if isinstance(node, list):
            if not part.lstrip("-").isdigit() or not -len(node) <= int(part) < len(node):
                raise ConfigError(where, f"index must be an integer in [0, {len(node) - 1}]")
            key: Any = int(part)
        elif isinstance(node, dict):
            if part not in node:
                raise ConfigError(where, f"unknown key; allowed keys are {', '.join(node)}")
            key = part
        else:
            raise ConfigError(where, "cannot index into a scalar value")
        if last:
            node[key] = value
        else:
            node = node[key]
    return from_dict(type(config), data)


def get_path(config: Any, path: str) -> Any:
    """The value at dotted ``path``; raises ``ConfigError`` for an unknown path."""
    node: Any = to_dict(config)
    for i, part in enumerate(path.split(".")):
        where = ".".join(path.split(".")[: i + 1])
        if isinstance(node, list) and part.isdigit() and int(part) < len(node):
            node = node[int(part)]
        elif isinstance(node, dict) and part in node:
            node = node[part]
        else:
            raise ConfigError(where, "unknown field path")
    return node


# ---------------------------------------------------------------------------- TOML
def _toml_scalar(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value) or math.isinf(value):
            raise ValueError("TOML output of non-finite floats is not supported")
        return repr(value)
    if isinstance(value, str):
        escaped = value.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n")
        return f'"{escaped}"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_scalar(v) for v in value) + "]"
    if value is None:
        raise ValueError("TOML has no null; omit the key instead")
    raise TypeError(f"cannot write {type(value).__name__} to TOML")


def _is_table_list(value: Any) -> bool:
    return isinstance(value, list) and bool(value) and all(isinstance(v, dict) for v in value)


def dumps_toml(data: dict[str, Any], _prefix: str = "") -> str:
    """A small TOML writer for config dicts (tables, arrays of tables, scalars, lists)."""
    lines: list[str] = []
    nested: list[tuple[str, Any]] = []
    for key, value in data.items():
        if value is None:
            continue
        if isinstance(value, dict) or _is_table_list(value):
            nested.append((key, value))
        else:
            lines.append(f"{key} = {_toml_scalar(value)}")
    for key, value in nested:
        name = f"{_prefix}.{key}" if _prefix else key
        if isinstance(value, dict):
            lines.append("")
            lines.append(f"[{name}]")
            body = dumps_toml(value, name)
            if body:
                lines.append(body)
        else:
            for item in value:
                lines.append("")
                lines.append(f"[[{name}]]")
                body = dumps_toml(item, name)
                if body:
                    lines.append(body)
    return "\n".join(lines).strip("\n") + ("\n" if not _prefix else "")


def load_toml(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read a TOML file; a syntax error becomes a ``ConfigError`` naming the file."""
    path = Path(path)
    try:
        with path.open("rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError:
        raise ConfigError(str(path), "file not found") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(str(path), f"invalid TOML: {exc}") from None


def config_from_file(path: str | os.PathLike[str], build: "Callable[[dict[str, Any]], T]") -> T:
    """``build(toml_dict)`` for the file at ``path``; every error names the file, once."""
    try:
        return build(load_toml(path))
    except ConfigError as exc:
        if exc.field.startswith(str(path)):  # already about the file itself (missing, bad TOML)
            raise
        raise exc.under(f"{path}: ") from None


def atomic_write_text(path: str | os.PathLike[str], text: str) -> None:
    """Write ``text`` so readers see either the old file or the whole new one."""
    atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> None:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    umask = os.umask(0)
    os.umask(umask)
    try:
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; results are ordinary files
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def atomic_write_figure(fig: Any, path: str | os.PathLike[str], dpi: int = 120) -> Path:
    """Lay out, write atomically (format from the suffix, PNG without one) and close a figure."""
    import io

    import matplotlib.pyplot as plt

    path = Path(path)
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format=path.suffix.lstrip(".") or "png", dpi=dpi)
    plt.close(fig)
    atomic_write_bytes(path, buffer.getvalue())
    return path


def save_toml(config: Any, path: str | os.PathLike[str]) -> None:
    atomic_write_text(path, dumps_toml(to_dict(config)))

