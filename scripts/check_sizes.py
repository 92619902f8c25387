"""Fails when a module, class or function of viewcomp grows past its size limit.

Limits (lines, from the ``def``/``class`` line, decorators included, to the last line of the
body): a module 600, a class 300, a function 80. A function that must stay one piece says why
in a comment on the line before its ``def`` (or its first decorator) that starts with
``# one piece:``; it is then reported but does not fail. Tests are not measured.

Usage: ``python scripts/check_sizes.py [--list]`` (``--list``: every measured item over half
its limit, largest first). Exit status 1 when something is over its limit.
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("calib", "rt", "viewcomp", "shaders", "scripts", "bench", "examples")
MODULE_MAX, CLASS_MAX, FUNCTION_MAX = 600, 300, 80
WAIVER = "# one piece:"


def _start(node: ast.AST) -> int:
    decorators = getattr(node, "decorator_list", [])
    return min([node.lineno] + [d.lineno for d in decorators])  # type: ignore[attr-defined]


def _waived(lines: list[str], start: int) -> bool:
    """A ``# one piece:`` comment on one of the comment lines just above ``start``."""
    i = start - 2
    while i >= 0 and lines[i].strip().startswith("#"):
        if lines[i].strip().startswith(WAIVER):
            return True
        i -= 1
    return False


def measure(path: Path) -> list[tuple[str, str, int, int, bool]]:
    """(kind, name, lines, limit, waived) of the module and each class and function."""
    text = path.read_text(encoding="utf-8")
    lines = text.splitlines()
    out = [("module", "", len(lines), MODULE_MAX, False)]
    tree = ast.parse(text, filename=str(path))

    def walk(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
                name = f"{prefix}{child.name}"
                start = _start(child)
                n = (child.end_lineno or child.lineno) - start + 1
                if isinstance(child, ast.ClassDef):
                    out.append(("class", name, n, CLASS_MAX, False))
                else:
                    out.append(("function", name, n, FUNCTION_MAX, _waived(lines, start)))
                walk(child, name + ".")
            else:
                walk(child, prefix)

    walk(tree, "")
    return out


def main(argv: list[str]) -> int:
    show_all = "--list" in argv
    failed = 0
    rows = []
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            rel = path.relative_to(ROOT).as_posix()
            for kind, name, n, limit, waived in measure(path):
                if n > limit or (show_all and n > limit // 2):
                    rows.append((n / limit, rel, kind, name, n, limit, waived))
    for _, rel, kind, name, n, limit, waived in sorted(rows, reverse=True):
        where = f"{rel}:{name}" if name else rel
        if n <= limit:
            print(f"ok      {kind:8} {n:5d}/{limit} {where}")
        elif waived:
            print(f"one     {kind:8} {n:5d}/{limit} {where} (one piece, says why)")
        else:
            failed += 1
            print(f"TOO BIG {kind:8} {n:5d}/{limit} {where}")
    if failed:
        print(
            f"check_sizes: {failed} over the limits (module {MODULE_MAX}, class {CLASS_MAX}, "
            f"function {FUNCTION_MAX} lines)",
            file=sys.stderr,
        )
        return 1
    print("check_sizes: within the limits")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
