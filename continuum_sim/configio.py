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
        if not field.isprintable():  # a key with a newline or control character: escape it, keep one line
            field = repr(field)[1:-1]
        if len(field) > 200:  # a hostile key name: keep the message one readable line
            field = field[:120] + f"…({len(field)} characters)"
        self.field = field
        self.message = message
        super().__init__(f"{field}: {message}")

    def under(self, prefix: str) -> ConfigError:
        """The same error with its field path prefixed by the parent's path."""
        if not prefix:
            return self
        joiner = "" if self.field.startswith("[") or prefix.endswith(" ") else "."
        return ConfigError(f"{prefix}{joiner}{self.field}", self.message)


# --------------------------------------------------------------------------- checks
MAX_ECHO = 80  # characters of a value echoed in an error message (a 100 kB value must not flood the terminal)


def shorten(value: object, limit: int = MAX_ECHO) -> str:
    """``repr(value)`` cut to ``limit`` characters, saying how long it was."""
    text = repr(value)
    if len(text) <= limit:
        return text
    return f"{text[: limit - 1]}… ({len(text)} characters)"


def require_finite(field: str, value: float) -> None:
    if not math.isfinite(value):
        raise ConfigError(field, f"must be a finite number (got {shorten(value)})")


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
        raise ConfigError(field, f"must satisfy {lo}{field.split('.')[-1]}{hi} (got {shorten(value)})")


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
        raise ConfigError(field, f"must be an integer (got {shorten(value)})")
    if value < low or (high is not None and value > high):
        name = field.split(".")[-1]
        bound = f"{low} <= {name}" + ("" if high is None else f" <= {high}")
        raise ConfigError(field, f"must satisfy {bound}{hint} (got {value})")


# ------------------------------------------------------------ removed and renamed keys
# Config paths that existed once and are gone: old dotted path -> (the path that replaces it, or None,
# why, in a few words). Every unknown-key error (a scenario TOML, a study spec's [config] table, grid
# path, design variable or registry path) looks here first, so a file written for an older version
# fails with one line naming what to write instead. ``<k>`` in a replacement is a section index;
# an old path given with an index (``model.section_stiffness_scale.1``) fills it in.
MIGRATIONS: dict[str, tuple[str | None, str]] = {
    "model.section_stiffness_scale": (
        "arm.sections.<k>.stiffness_scale",
        "one stiffness factor per section; the model-wide list multiplied the same springs a second time",
    ),
    "scene.kerf_cell_length": (
        "scene.foam.voxel_size",
        "the kerf is cut out of the foam's voxels; there are no pre-built kerf cells any more",
    ),
    "scene.tools.cutter_shell": (
        None,
        "the cutter is no contact geom (it meets the foam's voxels), so it has no detection shell",
    ),
    "scene.foam.native": (
        None,
        "the voxel work always runs in the compiled kernels; the numpy path is gone",
    ),
}


def _dotted(path: str) -> str:
    """``arm.sections[0].x`` -> ``arm.sections.0.x`` (the form the table and the study specs use)."""
    return path.replace("[", ".").replace("]", "").strip(".")


def migration_note(path: str) -> str | None:
    """One line for a removed or renamed config ``path`` (or a path below one): what replaces it and why; else None."""
    dotted = _dotted(path)
    for old, (new, why) in MIGRATIONS.items():
        if dotted != old and not dotted.startswith(old + "."):
            continue
        if new is None:
            return f"removed, nothing replaces it ({why})"
        rest = dotted[len(old) + 1:]
        if "<k>" in new and rest.isdigit():
            new = new.replace("<k>", rest)
        return f"removed; use {new} instead ({why})"
    return None


def unknown_path_error(where: str, message: str, path: str = "") -> ConfigError:
    """The error for an unknown config key at ``where``: ``message``, or the migration note when the path was removed or renamed.

    ``path``: the whole dotted path asked for, when ``where`` is only the part of it that failed.
    """
    full = path or where
    note = migration_note(full)
    return ConfigError(full, note) if note is not None else ConfigError(where, message)


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
            raise ConfigError(field, f"must be {_type_name(tp)} (got {shorten(value)})")
        return value
    if isinstance(tp, type) and dataclasses.is_dataclass(tp):
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
            raise ConfigError(field, f"must be a number (got {type(value).__name__} {shorten(value)})")
        value = float(value)
        require_finite(field, value)
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            if isinstance(value, float) and value.is_integer():
                return int(value)
            raise ConfigError(field, f"must be an integer (got {type(value).__name__} {shorten(value)})")
        return value
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(field, f"must be true or false (got {shorten(value)})")
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
    names = [f.name for f in dataclasses.fields(cls) if f.init]  # type: ignore[arg-type]  # T is a dataclass type
    for key in data:
        if key not in names:
            where = f"{prefix}.{key}" if prefix else key
            raise unknown_path_error(where, f"unknown key; allowed keys are {', '.join(names)}")
    kwargs = {}
    for name in names:
        if name in data:
            where = f"{prefix}.{name}" if prefix else name
            kwargs[name] = _convert(hints[name], data[name], where)
    required = [f.name for f in dataclasses.fields(cls)  # type: ignore[arg-type]
                if f.init and f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING]
    for name in required:
        if name not in data:
            where = f"{prefix}.{name}" if prefix else name
            raise ConfigError(where, f"missing; required keys here are {', '.join(required)}")
    try:
        return cls(**kwargs)
    except ConfigError as exc:
        raise exc.under(prefix) from None


def set_path(data: Any, path: str, value: Any) -> None:
    """Set the value at dotted ``path`` (``sections.0.length``) inside a config's dict form, in place."""
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
                raise unknown_path_error(where, f"unknown key; allowed keys are {', '.join(node)}", path)
            key = part
        else:
            raise ConfigError(where, "cannot index into a scalar value")
        if last:
            node[key] = value
        else:
            node = node[key]


def replace_path(config: T, path: str, value: Any) -> T:
    """A copy of ``config`` with the field at dotted ``path`` (``sections.0.length``) set."""
    data = to_dict(config)
    set_path(data, path, value)
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
            raise unknown_path_error(where, "unknown field path", path)
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


MAX_CONFIG_BYTES = 16 * 1024 * 1024  # a configuration or spec file larger than this is not a configuration
MAX_CONFIG_DEPTH = 32  # tables/arrays nested deeper than this: no config of this package needs more than 5


def _depth(value: Any, limit: int) -> int:
    """Nesting depth of dicts/lists, iteratively (a hostile file must not exhaust the stack)."""
    deepest = 0
    stack: list[tuple[Any, int]] = [(value, 0)]
    while stack:
        node, level = stack.pop()
        if isinstance(node, dict):
            children = list(node.values())
        elif isinstance(node, list):
            children = node
        else:
            continue
        deepest = max(deepest, level + 1)
        if deepest > limit:
            return deepest
        stack.extend((child, level + 1) for child in children)
    return deepest


def read_config_text(path: str | os.PathLike[str]) -> str:
    """The text of a configuration file; anything that is not a readable UTF-8 file is a ``ConfigError``."""
    path = Path(path)
    where = str(path)
    try:
        if path.is_dir():
            raise ConfigError(where, "is a folder, not a TOML file")
        if path.exists() and not path.is_file():
            raise ConfigError(where, "is not a regular file (a device or pipe?); give a TOML file")
        size = path.stat().st_size
        if size > MAX_CONFIG_BYTES:
            raise ConfigError(where, f"is {size} bytes; a configuration file may be at most {MAX_CONFIG_BYTES} bytes")
        raw = path.read_bytes()
    except FileNotFoundError:
        raise ConfigError(where, "file not found") from None
    except PermissionError:
        raise ConfigError(where, "cannot read the file (permission denied)") from None
    except OSError as exc:
        raise ConfigError(where, f"cannot read the file ({exc.strerror or exc})") from None
    except ValueError as exc:  # e.g. an embedded NUL byte in the path
        if isinstance(exc, ConfigError):
            raise
        raise ConfigError("path", f"not a usable file name ({exc}): {shorten(where)}") from None
    if raw[:2] in (b"\xff\xfe", b"\xfe\xff"):
        raise ConfigError(where, "is UTF-16 text; TOML files must be UTF-8 (re-save it as UTF-8)")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(where, f"is not UTF-8 text (byte {exc.start}); TOML files are UTF-8 (binary file?)") from None
    return text.removeprefix("\ufeff")


def parse_toml_text(text: str, where: str) -> dict[str, Any]:
    """Parse TOML text; syntax errors and absurd nesting become a ``ConfigError`` naming ``where``."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(where, f"invalid TOML: {exc}") from None
    except RecursionError:
        raise ConfigError(where, f"nested too deeply (at most {MAX_CONFIG_DEPTH} levels of tables and arrays)") from None
    if _depth(data, MAX_CONFIG_DEPTH) > MAX_CONFIG_DEPTH:
        raise ConfigError(where, f"nested too deeply (at most {MAX_CONFIG_DEPTH} levels of tables and arrays)")
    return data


def load_toml(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read a TOML file; a missing/unreadable/binary/non-UTF-8 file or bad syntax is a ``ConfigError`` naming it."""
    return parse_toml_text(read_config_text(path), str(path))


def config_from_file(path: str | os.PathLike[str], build: Callable[[dict[str, Any]], T]) -> T:
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



# ------------------------------------------------------------------- output folders
SYSTEM_TREES = ("/proc", "/sys", "/dev")  # kernel/device trees: never a place for results
NAME_MAX = 255  # bytes per path component on Linux file systems
PATH_MAX = 4096


def check_output_path(text: str, option: str = "--out") -> None:
    """What is wrong with any output path, file or folder: empty, NUL byte, too long, under /proc, /sys or /dev.

    The CLI boundary applies it to every command's ``--out`` before the command runs.
    """
    if not text.strip():
        raise ConfigError(option, "must name an output path (got an empty string)")
    if "\0" in text:
        raise ConfigError(option, f"contains a NUL byte: {shorten(text)}")
    encoded = os.fsencode(text)
    if len(encoded) >= PATH_MAX:
        raise ConfigError(option, f"path is {len(encoded)} bytes; at most {PATH_MAX - 1} allowed: {shorten(text)}")
    for part in Path(text).parts:
        if len(os.fsencode(part)) > NAME_MAX:
            raise ConfigError(option, f"a folder name is {len(os.fsencode(part))} bytes; at most {NAME_MAX} allowed: {shorten(part)}")
    absolute = Path(os.path.abspath(text))
    for tree in SYSTEM_TREES:
        if absolute == Path(tree) or Path(tree) in absolute.parents:
            raise ConfigError(option, f"{shorten(str(absolute))} is under {tree}, a system tree; write results elsewhere")


def check_output_dir(path: str | os.PathLike[str], option: str = "--out", create: bool = True) -> Path:
    """Check (and with ``create`` make) an output folder; every problem is one ``ConfigError`` naming ``option``.

    Refused before any work: an empty name, a NUL byte, a component longer than 255
    bytes, a path under /proc, /sys or /dev, an existing file, a parent that is a file
    or cannot be written.
    """
    text = os.fspath(path)
    if not isinstance(text, str) or not text.strip():
        raise ConfigError(option, "must name a folder (got an empty string); e.g. runs/my_run")
    check_output_path(text, option)
    out = Path(text)
    absolute = Path(os.path.abspath(text))
    if out.exists() and not out.is_dir():
        raise ConfigError(option, f"{shorten(text)} exists and is not a folder; give a folder path")
    ancestor = absolute
    while not ancestor.exists():
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        raise ConfigError(option, f"{shorten(str(ancestor))} is a file, so {shorten(text)} cannot be a folder")
    target = absolute if absolute.exists() else ancestor
    if not os.access(target, os.W_OK | os.X_OK):
        raise ConfigError(option, f"{shorten(str(target))} is not writable (permission denied)")
    if create:
        try:
            out.mkdir(parents=True, exist_ok=True)
            probe = tempfile.NamedTemporaryFile(dir=out, prefix=".write-test.", delete=True)  # noqa: SIM115
            probe.close()
        except OSError as exc:
            raise ConfigError(option, f"cannot write into {shorten(text)} ({exc.strerror or exc})") from None
    return out
