"""Fail on any import cycle among viewcomp's modules.

Every import counts: at module level, inside functions (lazy) and under ``if TYPE_CHECKING``,
because each of them is a dependency a reader has to follow. So do loads through
``importlib.import_module`` (and ``__import__``): a constant name is one edge; a name built
at run time (an f-string, ``"prefix." + name``) is an edge to every module whose name starts
with its constant prefix, e.g. the command table that ``viewcomp.cli`` loads as
``f"viewcomp.commands.{name}"`` is an edge to each module of ``viewcomp.commands``.
The packages are found through pyproject.toml's ``package-dir`` mapping (``viewcomp.calib``
lives in ``calib/``, and so on).

Usage: ``python scripts/check_imports.py`` (exit 0: no cycle; exit 1: the cycles, one a line).
"""

from __future__ import annotations

import ast
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def package_dirs() -> dict[str, Path]:
    """Top-level import package name -> its folder, from pyproject.toml."""
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())
    mapping = meta["tool"]["setuptools"]["package-dir"]
    return {name: ROOT / folder for name, folder in mapping.items()}


def module_files() -> dict[str, Path]:
    """Every module of viewcomp: dotted name -> file."""
    found: dict[str, Path] = {}
    for pkg, folder in package_dirs().items():
        for path in folder.rglob("*.py"):
            rel = path.relative_to(folder).with_suffix("")
            parts = [p for p in rel.parts if p != "__init__"]
            # a sub-folder that is itself a mapped package is found under its own name
            name = ".".join([pkg, *parts])
            if name.split(".")[:2] != pkg.split(".")[:2] and "." in pkg:
                continue
            found.setdefault(name, path)
    # mapped sub-packages win over the same folder reached from a parent mapping
    return found


def imports_of(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The viewcomp modules that ``name`` (at ``path``) imports, anywhere in the file."""
    is_pkg = path.name == "__init__.py"
    here = name if is_pkg else name.rpartition(".")[0]
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Call):
            out |= dynamic_imports(node, modules) - {name}
            continue
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = here.split(".")
                base = base[: len(base) - (node.level - 1)]
                stem = ".".join(base + ([node.module] if node.module else []))
            else:
                stem = node.module or ""
            targets = []
            for alias in node.names:
                sub = f"{stem}.{alias.name}"
                targets.append(sub if sub in modules else stem)
        else:
            continue
        for target in targets:
            # the deepest known module that the dotted name starts with
            parts = target.split(".")
            while parts and ".".join(parts) not in modules:
                parts.pop()
            if parts and ".".join(parts) != name:
                out.add(".".join(parts))
    return out


def _constant_prefix(arg: ast.expr) -> tuple[str, bool]:
    """(the constant text an import name starts with, whether that is the whole name)."""
    if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
        return arg.value, True
    if isinstance(arg, ast.JoinedStr):
        text = ""
        for part in arg.values:
            if not (isinstance(part, ast.Constant) and isinstance(part.value, str)):
                return text, False
            text += part.value
        return text, True
    if isinstance(arg, ast.BinOp) and isinstance(arg.op, ast.Add):
        left, whole = _constant_prefix(arg.left)
        if not whole:
            return left, False
        right, right_whole = _constant_prefix(arg.right)
        return left + right, right_whole
    return "", False


def dynamic_imports(call: ast.Call, modules: dict[str, Path]) -> set[str]:
    """The viewcomp modules an ``importlib.import_module(...)`` or ``__import__(...)`` call can
    load (see the module docstring); empty for any other call."""
    f = call.func
    is_import = (isinstance(f, ast.Attribute) and f.attr == "import_module") or (
        isinstance(f, ast.Name) and f.id in ("import_module", "__import__")
    )
    if not is_import or not call.args:
        return set()
    prefix, whole = _constant_prefix(call.args[0])
    if whole:
        return {prefix} if prefix in modules else set()
    if not prefix.startswith("viewcomp"):
        return set()
    return {m for m in modules if m.startswith(prefix) and m != prefix.rstrip(".")}


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    counter = 0
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            advanced = False
            for child in children:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.get(child, ())))))
                    advanced = True
                    break
                if child in on_stack:
                    low[node] = min(low[node], index[child])
            if advanced:
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    top = stack.pop()
                    on_stack.discard(top)
                    component.append(top)
                    if top == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return found


def main() -> int:
    modules = module_files()
    graph = {name: imports_of(name, path, modules) for name, path in modules.items()}
    found = cycles(graph)
    for component in found:
        print("import cycle: " + " <-> ".join(component))
    if found:
        print(f"{len(found)} import cycle(s) among {len(modules)} modules", file=sys.stderr)
        return 1
    print(f"no import cycle among {len(modules)} modules")
    return 0


if __name__ == "__main__":
    sys.exit(main())
