"""The architecture is a test: data flows one way (DESIGN.md), no import cycle, no upward import.

Layers, bottom to top (a module may import from its own layer and those below)::

    _checks, _io -> data -> promp -> library -> systems -> sim -> scenario -> evaluation, commands,
                                                                             benchmarks, cli

Imports inside functions count: a lazy import is still an arrow.
"""
import ast
import subprocess
import sys
from pathlib import Path

import drake_skills

PACKAGE = Path(drake_skills.__file__).parent
#: Bottom to top; a name matches itself and everything under it.
LAYERS = (
    ("drake_skills._checks", "drake_skills._io"),
    ("drake_skills.data",),
    ("drake_skills.promp",),
    ("drake_skills.library",),
    ("drake_skills.systems",),
    ("drake_skills.sim",),
    ("drake_skills.scenario",),
    ("drake_skills.evaluation", "drake_skills.commands", "drake_skills.benchmarks", "drake_skills.cli",
     "drake_skills"),
)


def _modules() -> dict[str, Path]:
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = path
    return out


def import_graph() -> dict[str, set[str]]:
    """Module -> the package modules it imports (module level and inside functions)."""
    modules = _modules()
    graph = {}
    for name, path in modules.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        targets = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                targets |= {a.name for a in node.names}
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    base = ".".join(package.split(".")[: len(package.split(".")) - node.level + 1] + [base]).strip(".")
                for a in node.names:
                    targets.add(f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base)
        graph[name] = {t for t in targets if t in modules and t != name}
    return graph


def layer_of(module: str) -> int:
    best, level = -1, None
    for i, names in enumerate(LAYERS):
        for n in names:
            if (module == n or module.startswith(n + ".")) and len(n) > best:
                best, level = len(n), i
    assert level is not None, f"module {module} is in no layer of tests/test_layering.py"
    return level


def test_no_module_imports_from_a_layer_above_it():
    upward = sorted(f"{a} (layer {layer_of(a)}) imports {b} (layer {layer_of(b)})"
                    for a, targets in import_graph().items() for b in targets if layer_of(b) > layer_of(a))
    assert not upward, "\n".join(upward)


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on_stack, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            scc = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                scc.append(w)
                if w == v:
                    break
            if len(scc) > 1:
                out.append(sorted(scc))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_no_import_cycle():
    assert not _cycles(import_graph()), _cycles(import_graph())


def test_the_checks_find_a_cycle_and_an_upward_import():
    """The two tests above can fail: a planted cycle and a planted upward arrow are found."""
    graph = {k: set(v) for k, v in import_graph().items()}
    graph["drake_skills.data.demonstration"].add("drake_skills.library.incremental")
    assert any("drake_skills.data.demonstration" in c for c in _cycles(graph))
    assert layer_of("drake_skills.library.incremental") > layer_of("drake_skills.data.demonstration")
    assert layer_of("drake_skills.sim.salad_robot") < layer_of("drake_skills.scenario.salad")
    assert "drake_skills.sim.models" in import_graph()["drake_skills.scenario.salad"]


CODE = r"""
import importlib, pkgutil, sys
import drake_skills.data, drake_skills.promp, drake_skills.library
names = []
for pkg in (drake_skills.data, drake_skills.promp, drake_skills.library):
    names += [m.name for m in pkgutil.walk_packages(pkg.__path__, pkg.__name__ + ".")]
for n in names:
    importlib.import_module(n)
assert "pydrake" not in sys.modules, [m for m in sys.modules if m.startswith("pydrake")]
print(len(names))
"""


def test_core_modules_do_not_import_pydrake():
    out = subprocess.run([sys.executable, "-c", CODE], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    # data: demonstration, demos, lasa, workspace; promp: 4; library: batch, incremental, labels, storage
    assert int(out.stdout.split()[-1]) >= 12, out.stdout
