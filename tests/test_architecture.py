"""The house's rules (docs/architecture.md), checked on the code as it stands: the pipeline's
layers (import-linter's contract in pyproject.toml), no import cycle between any two modules
(imports inside functions included), modules a reader can hold, no private name shared."""
import ast
import shutil
import subprocess
import sys
from collections import defaultdict

import pytest
from places import REPO

ROOT = REPO
PACKAGE = ROOT / "mimunav"
MAX_MODULE_LINES = 600
MAX_FUNCTION_LINES = 80


def _modules(package=PACKAGE):
    """{module name: (path, parsed tree)} of every module of the package."""
    out = {}
    for path in sorted(package.rglob("*.py")):
        parts = path.relative_to(package.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = (path, ast.parse(path.read_text()))
    return out


def import_graph(modules):
    """{module: {modules it imports}} from every import statement, at any depth: a module
    imported from a package imports the package's __init__ too."""
    edges = defaultdict(set)
    for name, (path, tree) in modules.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                base = package.split(".")[:len(package.split(".")) - node.level + 1] \
                    if node.level else []
                target = ".".join(base + ([node.module] if node.module else []))
                targets = [f"{target}.{a.name}" if f"{target}.{a.name}" in modules else target
                           for a in node.names]
            elif isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            else:
                continue
            for target in targets:
                parts = target.split(".")
                for k in range(1, len(parts) + 1):
                    ancestor = ".".join(parts[:k])
                    if ancestor in modules and ancestor != name and \
                            not name.startswith(ancestor + "."):
                        edges[name].add(ancestor)
    return edges


def cycles(edges):
    """The strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in edges.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                out.append(sorted(component))
    for v in list(edges):
        if v not in index:
            visit(v)
    return out


@pytest.mark.slow
def test_no_two_modules_import_each_other():
    """Not even through an import inside a function (those had hidden four cycles)."""
    assert cycles(import_graph(_modules())) == []


def test_a_cycle_is_seen_through_an_import_inside_a_function(tmp_path):
    """The check itself: two modules importing each other, one at the top and one inside a
    function, are a cycle."""
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from .b import g\n")
    (pkg / "b.py").write_text("def g():\n    from . import a\n    return a\n")
    assert cycles(import_graph(_modules(pkg))) == [["pkg.a", "pkg.b"]]


def test_each_stage_imports_only_the_stages_below_it():
    """import-linter's layers contract (pyproject.toml [tool.importlinter])."""
    lint = shutil.which("lint-imports") or pytest.fail("lint-imports is missing: "
                                                       "pip install -e '.[test]'")
    run = subprocess.run([lint, "--no-cache"], cwd=ROOT, capture_output=True, text=True)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-2000:]


def _compiled(node):
    """A numba kernel (decorated with njit)."""
    return any("njit" in ast.unparse(d) for d in node.decorator_list)


@pytest.mark.slow
def test_modules_and_functions_a_reader_can_hold():
    """No module over MAX_MODULE_LINES lines; no function over MAX_FUNCTION_LINES but a
    compiled kernel (whose docstring says why it stays whole)."""
    long_modules, long_functions = [], []
    for name, (path, tree) in _modules().items():
        lines = len(path.read_text().splitlines())
        if lines > MAX_MODULE_LINES:
            long_modules.append(f"{name}: {lines}")
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                length = node.end_lineno - node.lineno + 1
                if length > MAX_FUNCTION_LINES and not _compiled(node):
                    long_functions.append(f"{name}.{node.name}: {length}")
    assert long_modules == [] and long_functions == []


@pytest.mark.slow
def test_no_private_name_is_used_outside_its_module():
    """A name shared between modules is public, with a docstring."""
    modules = _modules()
    used = []
    for name, (path, tree) in modules.items():
        aliases = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and (node.level or
                                                     (node.module or "").startswith("mimunav")):
                for a in node.names:
                    if a.name.startswith("_") and not a.name.startswith("__"):
                        used.append(f"{name} imports {a.name}")
                    aliases.add(a.asname or a.name)
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and \
                    node.value.id in aliases and node.attr.startswith("_") and \
                    not node.attr.startswith("__"):
                used.append(f"{name} uses {node.value.id}.{node.attr}")
    assert used == []


def test_the_cli_starts_without_the_numeric_stack():
    """Building the parser of every command imports none of numba, scipy, matplotlib or
    numpy-quaternion: they load with the command that needs them."""
    probe = ("import sys; from mimunav.cli import build_parser; build_parser(); "
             "print(sorted({m.split('.')[0] for m in sys.modules} & "
             "{'numba', 'scipy', 'matplotlib', 'quaternion'}))")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                         check=True, cwd=ROOT).stdout.strip()
    assert out == "[]"
