"""The published results as a pipeline: what is stale, and regenerating it (DVC, ``dvc.yaml``).

    python scripts/results.py status             # list stale results; runs nothing (CI); exit 1 when any
    python scripts/results.py repro [STAGE ...]   # regenerate what is stale (or the named stages)
    python scripts/results.py fingerprint         # only rewrite pipeline/fingerprints/
    python scripts/results.py list                # every stage: what it makes, how long it takes

Every published table, figure and study folder is the output of one stage of ``dvc.yaml``.
A stage's declared inputs are its own spec and script, the shipped defaults
(``continuum_sim/data/scenario.toml``) and *fingerprints* of the package code it runs:
``pipeline/fingerprints/<group>.txt`` lists, for a group of modules (the import closure of
the group's entry modules, ``pipeline/groups.toml``), one hash per module of its code with
docstrings and comments removed (``ast.unparse``), so rewording a docstring stales nothing
while any change of what the code does stales every result made with it. The ``registry``
group is the parameter registry's table (units, status, sources, ranges), which the studies
sample. DVC compares each input's hash with the one ``dvc.lock`` recorded when the output was
made; ``git diff pipeline/fingerprints`` shows which modules changed.
"""

from __future__ import annotations

import argparse
import ast
import hashlib
import json
import os
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = "continuum_sim"
GROUPS = ROOT / "pipeline" / "groups.toml"
FINGERPRINTS = ROOT / "pipeline" / "fingerprints"


def module_files(root: Path = ROOT) -> dict[str, Path]:
    """Every module of the package: dotted name -> file."""
    out: dict[str, Path] = {}
    for path in sorted((root / PACKAGE).rglob("*.py")):
        rel = path.relative_to(root).with_suffix("")
        parts = list(rel.parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _imports(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The package modules ``name`` imports anywhere in its file (functions included)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    is_pkg = path.name == "__init__.py"
    package = name if is_pkg else name.rpartition(".")[0]
    found: set[str] = set()

    def add(target: str) -> None:
        while target and target not in modules:
            target = target.rpartition(".")[0]
        if target:
            found.add(target)

    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith(PACKAGE):
                    add(alias.name)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            if not mod.startswith(PACKAGE):
                continue
            for alias in node.names:
                full = f"{mod}.{alias.name}"
                add(full if full in modules else mod)
    # importing a.b.c runs a/__init__ and a/b/__init__ too
    for mod in list(found):
        parts = mod.split(".")
        for i in range(1, len(parts)):
            parent = ".".join(parts[:i])
            if parent in modules:
                found.add(parent)
    found.discard(name)
    return found


def closure(entries: list[str], exclude: list[str], modules: dict[str, Path]) -> list[str]:
    """The import closure of ``entries`` (each a module or a package prefix), minus ``exclude`` prefixes."""

    def excluded(mod: str) -> bool:
        return any(mod == ex or mod.startswith(ex + ".") for ex in exclude)

    todo = [m for m in modules if any(m == e or m.startswith(e + ".") for e in entries)]
    seen: set[str] = set()
    while todo:
        mod = todo.pop()
        if mod in seen or excluded(mod):
            continue
        seen.add(mod)
        todo.extend(_imports(mod, modules[mod], modules) - seen)
    return sorted(seen)


class _StripDocstrings(ast.NodeTransformer):
    def _strip(self, node: ast.AST) -> ast.AST:
        body = getattr(node, "body", None)
        if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) and isinstance(body[0].value.value, str):
            node.body = body[1:] or [ast.Pass()]  # type: ignore[attr-defined]
        self.generic_visit(node)
        return node

    visit_Module = visit_FunctionDef = visit_AsyncFunctionDef = visit_ClassDef = _strip


def code_hash(path: Path) -> str:
    """Hash of what a module does: its AST without docstrings, unparsed (comments and layout drop out)."""
    tree = _StripDocstrings().visit(ast.parse(path.read_text(encoding="utf-8")))
    return hashlib.sha256(ast.unparse(tree).encode()).hexdigest()[:16]


def data_hash(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()[:16]


def registry_table() -> str:
    """The registry's metadata as canonical JSON (what the studies sample: ranges, units, status)."""
    sys.path.insert(0, str(ROOT))
    from continuum_sim.params.registry import REGISTRY

    rows = [{"path": p.path, "unit": p.unit, "status": p.status, "range": p.range, "log": p.log, "source": p.source} for p in REGISTRY]
    return json.dumps(rows, sort_keys=True, ensure_ascii=False)


def fingerprints(root: Path = ROOT) -> dict[str, str]:
    """Text of each group's fingerprint file."""
    spec = tomllib.loads((root / "pipeline" / "groups.toml").read_text())
    modules = module_files(root)
    out: dict[str, str] = {}
    for group, entry in spec["group"].items():
        lines = [f"# {group}: {entry['why']}", "# module  code hash (docstrings and comments removed)"]
        for mod in closure(entry["entries"], entry.get("exclude", []), modules):
            lines.append(f"{mod}  {code_hash(modules[mod])}")
        for data in entry.get("data", []):
            for path in sorted(root.glob(data)):
                lines.append(f"{path.relative_to(root)}  {data_hash(path)}")
        out[group] = "\n".join(lines) + "\n"
    out["registry"] = "# registry: the parameter registry's table (units, status, sources, ranges)\n" + hashlib.sha256(
        registry_table().encode()
    ).hexdigest() + "\n"
    return out


def write_fingerprints(root: Path = ROOT) -> list[str]:
    """Rewrite pipeline/fingerprints/; the groups whose file changed."""
    folder = root / "pipeline" / "fingerprints"
    folder.mkdir(parents=True, exist_ok=True)
    changed = []
    for group, text in fingerprints(root).items():
        path = folder / f"{group}.txt"
        if not path.exists() or path.read_text() != text:
            path.write_text(text)
            changed.append(group)
    return changed


def _dvc(*args: str, capture: bool = True) -> subprocess.CompletedProcess[str]:
    exe = shutil.which("dvc") or str(Path(sys.executable).with_name("dvc"))
    if not Path(exe).exists() and not shutil.which(exe):
        sys.exit("results: dvc is not installed (pip install -e \".[test]\" installs it)")
    env = dict(os.environ, DVC_NO_ANALYTICS="1")
    return subprocess.run([exe, *args], cwd=ROOT, text=True, capture_output=capture, env=env, check=False)


def stage_outputs() -> dict[str, list[str]]:
    """Stage name -> the outputs it makes (from dvc.yaml)."""
    import yaml  # dvc depends on PyYAML

    doc = yaml.safe_load((ROOT / "dvc.yaml").read_text())
    out = {}
    for name, stage in doc["stages"].items():
        outs = []
        for item in stage.get("outs", []):
            outs.append(next(iter(item)) if isinstance(item, dict) else item)
        out[name] = outs
    return out


def stale() -> dict[str, list[str]]:
    """Stale stage -> why (DVC's status: changed deps, changed/missing outs, or never run)."""
    proc = _dvc("status", "--json")
    if proc.returncode != 0:
        sys.exit(f"results: dvc status failed: {proc.stderr.strip().splitlines()[-1] if proc.stderr.strip() else proc.returncode}")
    data = json.loads(proc.stdout or "{}")
    out: dict[str, list[str]] = {}
    for stage, entries in data.items():
        name = stage.split(":")[-1]
        reasons = []
        for entry in entries:
            if isinstance(entry, str):
                reasons.append(entry)
                continue
            for kind, files in entry.items():
                if isinstance(files, dict):
                    reasons.extend(f"{kind.replace('changed ', '')} {path}: {what}" for path, what in files.items())
                else:
                    reasons.append(f"{kind}: {files}")
        out[name] = reasons
    return out


def quoted_by(outputs: list[str], root: Path = ROOT) -> list[str]:
    """README.md and docs/*.md pages that quote any of ``outputs`` (link to it or read it in a check marker)."""
    pages = []
    for page in [root / "README.md", *sorted((root / "docs").glob("*.md"))]:
        text = page.read_text(encoding="utf-8")
        if any(out in text or Path(out).name in text and out.startswith("docs/") and Path(out).suffix for out in outputs):
            pages.append(str(page.relative_to(root)))
    return pages


def cmd_status(_: argparse.Namespace) -> int:
    changed = write_fingerprints()
    if changed:
        print(f"code fingerprints changed: {', '.join(changed)} (git diff pipeline/fingerprints shows which modules)")
    bad = stale()
    outs = stage_outputs()
    if not bad:
        print(f"results: 0 stale of {len(outs)} stages")
        return 0
    import yaml

    lock = ROOT / "dvc.lock"
    locked = set((yaml.safe_load(lock.read_text()) or {}).get("stages", {})) if lock.exists() else set()
    print(f"results: {len(bad)} stale of {len(outs)} stages (regenerate: python scripts/results.py repro)")
    for name, reasons in sorted(bad.items()):
        made = outs.get(name, [])
        print(f"  {name}: makes {', '.join(made) or '?'}")
        pages = [p for p in quoted_by(made) if p not in made]
        if pages:
            print(f"      quoted in {', '.join(pages)}")
        if name not in locked:
            print("      never made by the pipeline (no entry in dvc.lock)")
            continue
        for reason in reasons[:6]:
            print(f"      {reason}")
    return 1


def cmd_repro(args: argparse.Namespace) -> int:
    write_fingerprints()
    # --keep-going: one failing stage does not stop the independent ones (DVC skips only what depends on it)
    return _dvc("repro", "--keep-going", *args.stages, capture=False).returncode


def cmd_fingerprint(_: argparse.Namespace) -> int:
    changed = write_fingerprints()
    print(f"fingerprints rewritten: {', '.join(changed) or 'none changed'}")
    return 0


def cmd_list(_: argparse.Namespace) -> int:
    import yaml

    doc = yaml.safe_load((ROOT / "dvc.yaml").read_text())
    for name, stage in doc["stages"].items():
        print(f"{name}: {stage.get('desc', '')}")
        print(f"    {stage['cmd'] if isinstance(stage['cmd'], str) else ' && '.join(stage['cmd'])}")
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("status", help="list stale results without running anything; exit 1 when any").set_defaults(fn=cmd_status)
    repro = sub.add_parser("repro", help="regenerate what is stale (or the named stages)")
    repro.add_argument("stages", nargs="*")
    repro.set_defaults(fn=cmd_repro)
    sub.add_parser("fingerprint", help="rewrite pipeline/fingerprints/ only").set_defaults(fn=cmd_fingerprint)
    sub.add_parser("list", help="every stage and its command").set_defaults(fn=cmd_list)
    args = parser.parse_args(argv)
    return int(args.fn(args))


if __name__ == "__main__":
    sys.exit(main())
