"""The package's import graph (issue 13: one path through the package): no module imports
another that imports it back, directly or through others, counting imports at module level
and inside functions alike (a function-local import can hide a cycle, never break one)."""

from __future__ import annotations

import ast
from pathlib import Path

import kinmo
from repo_scripts import load_script

ROOT = Path(kinmo.__file__).resolve().parent


def _modules() -> dict[str, Path]:
    out = {}
    for p in ROOT.rglob("*.py"):
        parts = p.relative_to(ROOT.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = p
    return out


def _targets(node: ast.Import | ast.ImportFrom, module: str, is_package: bool, mods) -> set[str]:
    if isinstance(node, ast.Import):
        names = [a.name for a in node.names]
    else:
        if node.level:
            base = module.split(".") if is_package else module.split(".")[:-1]
            base = base[: len(base) - node.level + 1]
            pkg = ".".join(base + ([node.module] if node.module else []))
        else:
            pkg = node.module or ""
        # ``from pkg import sub`` runs ``pkg/__init__.py`` first: an edge to the package too
        names = [pkg] + [f"{pkg}.{a.name}" for a in node.names]
    out = set()
    for t in names:
        while t not in mods and "." in t:
            t = t.rsplit(".", 1)[0]
        if t in mods and t != module:
            out.add(t)
    return out


def import_graph() -> dict[str, set[str]]:
    """``module -> modules of kinmo it imports`` (any depth of the syntax tree; ``from
    kinmo.a import b`` imports the package ``kinmo.a`` as well as ``kinmo.a.b``)."""
    mods = _modules()
    graph: dict[str, set[str]] = {m: set() for m in mods}
    for m, p in mods.items():
        for n in ast.walk(ast.parse(p.read_text(encoding="utf-8"))):
            if isinstance(n, (ast.Import, ast.ImportFrom)):
                graph[m] |= _targets(n, m, p.name == "__init__.py", mods)
    return graph


def strongly_connected(graph: dict[str, set[str]]) -> list[list[str]]:
    """Components of more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    counter = 0
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    x = stack.pop()
                    on.discard(x)
                    comp.append(x)
                    if x == v:
                        break
                if len(comp) > 1:
                    out.append(sorted(comp))
    return out


def test_the_cycle_finder_finds_a_cycle():
    g = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert strongly_connected(g) == [["a", "b", "c"]]
    assert strongly_connected({"a": {"b"}, "b": set()}) == []


def test_the_graph_sees_function_local_imports():
    g = import_graph()
    assert len(g) > 100
    # kinmo.cli.pipeline imports kinmo.pipeline inside its command only (instant --help)
    assert "kinmo.pipeline" in g["kinmo.cli.pipeline"]


def test_no_import_cycle_in_kinmo():
    assert strongly_connected(import_graph()) == []


def test_the_module_map_lists_every_module():
    page = (ROOT.parents[1] / "docs" / "modules.md").read_text(encoding="utf-8")
    missing = [m for m in _modules() if f"`{m}`" not in page]
    assert missing == [], f"docs/modules.md lacks {missing}"


def _imports_upward(package: str, above: tuple[str, ...]) -> dict[str, list[str]]:
    """Modules of ``package`` (itself and below) that import a module of ``above``."""
    g = import_graph()
    bad = {m: sorted(t for t in g[m] if t.startswith(above))
           for m in g if m == package or m.startswith(package + ".")}
    return {m: t for m, t in bad.items() if t}


def test_refine_stays_below_inference_and_its_callers():
    # issue 22: refine/ is used by kinmo.inference, never the other way round
    assert _imports_upward("kinmo.refine", ("kinmo.predict", "kinmo.evaluate", "kinmo.inference",
                                            "kinmo.pseudo_label", "kinmo.pipeline")) == {}


def test_assets_stay_below_prediction_and_export():
    # issue 36: kinmo.assets reads a user's files into parts; what predicts or writes uses it
    assert _imports_upward("kinmo.assets", ("kinmo.user_input", "kinmo.predict", "kinmo.inference",
                                            "kinmo.export", "kinmo.cli", "kinmo.pipeline",
                                            "kinmo.evaluate", "kinmo.models", "kinmo.train")) == {}
    assert "kinmo.assets" in import_graph()["kinmo.user_input"]


#: Ceiling of function-local imports of kinmo modules outside kinmo/cli/ (issue 22: 211 -> 38,
#: counted by scripts/count_local_imports.py); lower it as imports move to module level.
LOCAL_IMPORT_CEILING = 29


def test_function_local_imports_stay_under_the_ceiling():
    mod = load_script("scripts/count_local_imports.py")
    found = mod.local_imports(ROOT)
    assert len(found) <= LOCAL_IMPORT_CEILING, "\n".join(f"{p}:{n}: {m}" for p, n, m in found)
    # the counter sees an import in a function, and leaves cli/ out
    assert not any("cli" in p.relative_to(ROOT).parts[:1] for p, _, _ in found)
