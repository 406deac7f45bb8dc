"""Count function-local imports of kinmo modules outside ``kinmo/cli/`` (issue 22).

An import of ``kinmo...`` (or a relative import) inside a function or method body counts
once per statement. ``kinmo/cli/`` is left out: Typer commands import lazily on purpose
(instant ``--help``).

Usage: ``python scripts/count_local_imports.py [--list]`` (prints the count; ``--list``
also prints ``path:line: statement`` per import).
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1] / "python" / "kinmo"


def local_imports(root: Path = ROOT) -> list[tuple[Path, int, str]]:
    """``(file, line, module)`` of each function-local kinmo import below ``root``, outside ``cli/``."""
    out: list[tuple[Path, int, str]] = []
    for p in sorted(root.rglob("*.py")):
        if "cli" in p.relative_to(root).parts[:1]:
            continue
        tree = ast.parse(p.read_text(encoding="utf-8"))
        for fn in ast.walk(tree):
            if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            for n in ast.walk(fn):
                if isinstance(n, ast.Import):
                    mods = [a.name for a in n.names if a.name.split(".")[0] == "kinmo"]
                elif isinstance(n, ast.ImportFrom):
                    mods = ([("." * n.level) + (n.module or "")] if n.level
                            else [n.module] if (n.module or "").split(".")[0] == "kinmo" else [])
                else:
                    continue
                if mods:
                    out.append((p, n.lineno, mods[0]))
    # a nested function's imports are walked from both functions: count each statement once
    return sorted(set(out))


def main() -> None:
    found = local_imports()
    if "--list" in sys.argv[1:]:
        for p, line, mod in found:
            print(f"{p.relative_to(ROOT.parent)}:{line}: {mod}")
    print(len(found))


if __name__ == "__main__":
    main()
