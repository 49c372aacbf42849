"""The module import graph of pito_core, app and pito_bench has no cycles.

The graph is built from the source with :mod:`ast` (no import is executed): every
``import``/``from ... import`` anywhere in a module counts, including those inside
functions, and relative imports are resolved.  ``from pkg import name`` counts as an
import of ``pkg.name`` when that is a module, else of ``pkg``.  A package's
``__init__`` is the module ``pkg``; a submodule does not import its parent package
implicitly (Python does, but every package is a node, so that edge would make every
``__init__`` re-export a cycle).
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("pito_core", "app", "pito_bench")


def _modules(packages=PACKAGES):
    """Map dotted module name -> source path for every .py under the packages."""
    out = {}
    for pkg in packages:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            is_pkg = parts[-1] == "__init__"
            if is_pkg:
                parts = parts[:-1]
            out[".".join(parts)] = (path, is_pkg)
    return out


def _resolve(name, level, current, is_pkg):
    if level == 0:
        return name
    base = current.split(".")
    if not is_pkg:
        base = base[:-1]
    if level > 1:
        base = base[: len(base) - (level - 1)]
    return ".".join(base + ([name] if name else []))


def import_graph(packages=PACKAGES):
    """Edges module -> {imported modules of ours}, with the line of the first import."""
    mods = _modules(packages)
    graph = {m: {} for m in mods}
    for mod, (path, is_pkg) in mods.items():
        tree = ast.parse(path.read_text(), filename=str(path))
        for node in ast.walk(tree):
            targets = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = _resolve(node.module or "", node.level, mod, is_pkg)
                for a in node.names:
                    sub = f"{base}.{a.name}"
                    targets.append(sub if sub in mods else base)
            for t in targets:
                # the deepest module of ours that t names
                while t and t not in mods:
                    t = t.rpartition(".")[0]
                if t and t != mod:
                    graph[mod].setdefault(t, node.lineno)
    return graph


def find_cycles(graph):
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, sccs = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                sccs.append(sorted(comp))

    import sys

    sys.setrecursionlimit(max(10000, sys.getrecursionlimit()))
    for v in graph:
        if v not in index:
            visit(v)
    return sccs


def _describe(graph, comp):
    comp = set(comp)
    return "\n".join(
        f"  {a} -> {b} (line {line})"
        for a in sorted(comp)
        for b, line in sorted(graph[a].items())
        if b in comp
    )


def test_graph_sees_function_level_and_relative_imports(tmp_path):
    """The builder must find a cycle hidden inside a function (so the test can fail)."""
    g = {"p": {}, "p.a": {"p.b": 1}, "p.b": {"p.a": 3}}
    assert find_cycles(g) == [["p.a", "p.b"]]
    assert _resolve("x", 1, "pito_core.io._csv", False) == "pito_core.io.x"
    assert _resolve("", 2, "pito_core.io._csv", False) == "pito_core"
    assert _resolve("_m", 1, "pito_core.io", True) == "pito_core.io._m"


@pytest.mark.parametrize("package", PACKAGES)
def test_no_import_cycles(package):
    graph = import_graph()
    cycles = [c for c in find_cycles(graph) if any(m.split(".")[0] == package for m in c)]
    # package __init__ re-exports: `pkg` imports `pkg._x`, and `pkg._x` importing `pkg`
    # (the public face of its own package) is a real cycle too; report everything.
    assert not cycles, "import cycles:\n" + "\n\n".join(_describe(graph, c) for c in cycles)


_LAUNCHERS = {"Popen", "run", "call", "check_call", "check_output", "system", "popen", "run_in_process",
              "create_subprocess_exec", "create_subprocess_shell", "execv", "execvp", "execve", "execl",
              "execlp", "spawnv", "spawnl", "spawnvp", "startDetached", "start"}
_LAUNCHED = re.compile(r"^(app|pito_bench)(\.|$)|^pito-app$|^bench$|\b(app|pito_bench)\.[a-z_]+\b|pito-app|\bpito bench\b")


def launches_of_app_or_bench(source: str):
    """(line, text) of every call that starts a process and names app/pito-app/pito_bench in its arguments."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, ast.Call):
            continue
        f = node.func
        name = f.attr if isinstance(f, ast.Attribute) else f.id if isinstance(f, ast.Name) else ""
        if name not in _LAUNCHERS:
            continue
        for arg in [*node.args, *(k.value for k in node.keywords)]:
            for c in ast.walk(arg):
                if isinstance(c, ast.Constant) and isinstance(c.value, str) and _LAUNCHED.search(c.value):
                    out.append((node.lineno, c.value))
    return out


def test_launch_scan_can_fail():
    src = 'import subprocess, sys\nsubprocess.Popen([sys.executable, "-m", "pito_bench._live_window"])\n'
    assert launches_of_app_or_bench(src) == [(2, "pito_bench._live_window")]
    assert launches_of_app_or_bench('os.execvp("pito-app", ["pito-app"])') != []
    assert launches_of_app_or_bench('print("run pito-app --pito X")') == []


def test_pito_core_never_starts_app_or_bench():
    """No subprocess/exec call in pito_core names the app or the benchmark (import-linter cannot see it)."""
    offenders = [
        f"{path.relative_to(ROOT)}:{line}: {text!r}"
        for path in sorted((ROOT / "pito_core").rglob("*.py"))
        for line, text in launches_of_app_or_bench(path.read_text())
    ]
    assert not offenders, "pito_core launches app/pito_bench:\n" + "\n".join(offenders)
