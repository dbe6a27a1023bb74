"""The house rules of ARCHITECTURE.md, read from the code's own imports (every ``import``
statement, including those inside functions and under ``TYPE_CHECKING``).

* Imports go only downwards: floor ← pure rooms ← ingest/storage ← use-cases ← doors; no door
  imports another door.
* No import cycle between rooms, nor between modules at import time.
* No module over 800 lines; no function over 100 lines of code without its reason, a
  ``# Long function: …`` comment right after its docstring.
"""

from __future__ import annotations

import ast
from collections import defaultdict
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

ROOMS: dict[str, str] = {
    # module prefix → room; the longest matching prefix wins
    "gearwatch": "floor",  # the namespace package: its __init__ only re-exports the version
    "gearwatch.floor": "floor",
    "dsp": "dsp",
    "detection": "detection",
    "physics": "physics",
    "ingest": "ingest",
    "storage": "storage",
    "gearwatch.usecases": "usecases",
    "gearwatch.cli": "cli",
    "gearwatch.worker": "worker",
    "gearwatch.__main__": "cli",
    "gearwatch.notebook": "notebook",
    "service": "service",
}

BELOW_USECASES = {"floor", "dsp", "detection", "physics", "ingest", "storage"}
ALLOWED: dict[str, set[str]] = {
    "floor": set(),
    "dsp": {"floor"},
    "detection": {"floor", "dsp"},
    # the simulated-campaign writers write their manifests with ingest's manifest writer
    "physics": {"floor", "dsp", "ingest"},
    "ingest": {"floor", "dsp"},
    "storage": {"floor", "detection"},
    "usecases": BELOW_USECASES,
    # the doors: parse, call a use-case, present; never another door
    "cli": BELOW_USECASES | {"usecases"},
    "service": BELOW_USECASES | {"usecases"},
    "worker": BELOW_USECASES | {"usecases"},
    # the Python door (notebooks): DataFrames of what the use-cases and storage answer
    "notebook": BELOW_USECASES | {"usecases"},
}


def room_of(module: str) -> str | None:
    best = None
    for prefix, room in ROOMS.items():
        if (module == prefix or module.startswith(prefix + ".")) and (
            best is None or len(prefix) > len(best[0])
        ):
            best = (prefix, room)
    return None if best is None else best[1]


def project_modules() -> dict[str, Path]:
    """Every module of the installed packages, by dotted name."""
    modules = {}
    for top in ("gearwatch", "dsp", "detection", "physics", "ingest", "storage", "service"):
        for path in sorted((ROOT / top).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            modules[".".join(parts)] = path
    return modules


def imported_modules(module: str, path: Path, known: set[str]) -> set[str]:
    """The project modules ``module`` imports anywhere in its text (``from p import name``
    counts as ``p.name`` when that is a module, else ``p``)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    return imports_in(tree, module, path, known)


def imports_in(tree: ast.AST, module: str, path: Path, known: set[str]) -> set[str]:
    """The project modules imported by the statements of ``tree``."""
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")
                anchor = anchor[: len(anchor) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            names = [f"{base}.{alias.name}" for alias in node.names]
        else:
            continue
        for name in names:
            while name and name not in known:
                name = name.rpartition(".")[0]
            if name:
                found.add(name)
    # A package's own ancestors are initialised before it by Python itself: not an edge.
    return {f for f in found if not (module == f or module.startswith(f + "."))}


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    modules = project_modules()
    known = set(modules)
    return {m: imported_modules(m, p, known) for m, p in modules.items()}


def test_every_module_is_in_a_room(graph: dict[str, set[str]]) -> None:
    assert [m for m in graph if room_of(m) is None] == []


def test_imports_only_go_downwards(graph: dict[str, set[str]]) -> None:
    wrong = []
    for module, targets in sorted(graph.items()):
        room = room_of(module)
        assert room is not None
        for target in sorted(targets):
            other = room_of(target)
            if other != room and other not in ALLOWED[room]:
                wrong.append(f"{module} ({room}) imports {target} ({other})")
    assert wrong == []


def cycles_of(edges: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one node (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for nxt in sorted(edges.get(node, ())):
            if nxt not in index:
                visit(nxt)
                low[node] = min(low[node], low[nxt])
            elif nxt in on_stack:
                low[node] = min(low[node], index[nxt])
        if low[node] == index[node]:
            component = []
            while True:
                top = stack.pop()
                on_stack.discard(top)
                component.append(top)
                if top == node:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for node in sorted(edges):
        if node not in index:
            visit(node)
    return cycles


def test_no_import_cycle_between_rooms(graph: dict[str, set[str]]) -> None:
    """The rooms are the packages of the old tangle (gearwatch ↔ ingest ↔ service ↔ storage),
    with ``gearwatch`` split into its floor, use-cases and doors."""
    edges: dict[str, set[str]] = defaultdict(set)
    for module, targets in graph.items():
        for target in targets:
            source, other = room_of(module), room_of(target)
            assert source is not None and other is not None
            if other != source:
                edges[source].add(other)
    assert cycles_of(edges) == []


def test_no_import_cycle_between_modules_at_import_time() -> None:
    """Module-level imports (what runs when a module is imported) form no cycle anywhere."""
    modules = project_modules()
    known = set(modules)
    edges: dict[str, set[str]] = {}
    for module, path in modules.items():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        top_level = ast.Module(
            body=[n for n in tree.body if isinstance(n, ast.Import | ast.ImportFrom)],
            type_ignores=[],
        )
        edges[module] = imports_in(top_level, module, path, known)
    assert cycles_of(edges) == []


def test_the_checks_see_a_wrong_import() -> None:
    """The rules above would catch the old tangle: storage importing a use-case, a door importing
    another door, and a cycle between two packages."""
    assert "usecases" not in ALLOWED["storage"]
    assert "cli" not in ALLOWED["service"] and "worker" not in ALLOWED["service"]
    assert room_of("gearwatch.usecases.analyze") == "usecases"
    assert room_of("gearwatch.floor.errors") == "floor"
    assert room_of("gearwatch.cli.commands.replay") == "cli"
    module = ROOT / "storage" / "repositories" / "base.py"
    known = {"storage.repositories.base", "gearwatch.floor.errors", "gearwatch.floor"}
    assert "gearwatch.floor.errors" in imported_modules("storage.repositories.base", module, known)


MAX_MODULE_LINES = 800

TO_SPLIT: dict[str, str] = {}
"""Modules known to be over the limit, each with its reason; every other module must hold."""


def test_no_module_over_800_lines() -> None:
    long = {
        str(path.relative_to(ROOT)): n
        for path in project_modules().values()
        if (n := len(path.read_text(encoding="utf-8").splitlines())) > MAX_MODULE_LINES
    }
    assert {name: n for name, n in long.items() if name not in TO_SPLIT} == {}


MAX_FUNCTION_LINES = 100
LONG_FUNCTION_REASON = "# Long function:"


def long_functions_without_reason(source: str) -> list[str]:
    """Functions whose code (the docstring not counted) is longer than
    :data:`MAX_FUNCTION_LINES` and that do not say why in a ``# Long function: …`` comment
    right after their docstring."""
    tree = ast.parse(source)
    lines = source.splitlines()
    found = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            continue
        first = node.body[0]
        documented = (isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant)
                      and isinstance(first.value.value, str))
        code_start = (first.end_lineno or first.lineno) + 1 if documented else first.lineno
        assert node.end_lineno is not None
        if node.end_lineno - code_start + 1 <= MAX_FUNCTION_LINES:
            continue
        if not lines[code_start - 1].strip().startswith(LONG_FUNCTION_REASON):
            found.append(f"{node.name} (line {node.lineno})")
    return found


def test_no_function_over_100_lines_without_its_reason() -> None:
    missing = {
        str(path.relative_to(ROOT)): names
        for path in project_modules().values()
        if (names := long_functions_without_reason(path.read_text(encoding="utf-8")))
    }
    assert missing == {}


def test_the_long_function_check_sees_a_long_function() -> None:
    body = "\n".join(f"    x{i} = {i}" for i in range(MAX_FUNCTION_LINES + 1))
    plain = f'def f():\n    """Doc."""\n{body}\n'
    assert long_functions_without_reason(plain) == ["f (line 1)"]
    reasoned = f'def f():\n    """Doc."""\n    {LONG_FUNCTION_REASON} one flat list.\n{body}\n'
    assert long_functions_without_reason(reasoned) == []
    short = "def f():\n" + "\n".join(f"    x{i} = {i}" for i in range(MAX_FUNCTION_LINES)) + "\n"
    assert long_functions_without_reason(short) == []


@pytest.mark.parametrize(
    ("module", "must_not_load"),
    [
        # `gearwatch --help` answers without any numerical or database library
        ("gearwatch.cli.main", ("numpy", "scipy", "sqlalchemy", "numba")),
        # storage, the service and every database command: scipy.stats alone took ~0.6 s there
        ("storage.repositories", ("scipy", "numba")),
        ("service.app", ("scipy", "numba", "matplotlib")),
        # the per-record chain with a tach: no scipy, no numba (ARCHITECTURE.md, start-up)
        ("gearwatch.usecases.analyze", ("scipy", "numba", "sqlalchemy")),
    ],
)
def test_start_up_imports_stay_light(module: str, must_not_load: tuple[str, ...]) -> None:
    """What importing a door or a room loads, in a fresh interpreter (the lazy imports that
    ARCHITECTURE.md's start-up paragraph promises)."""
    import subprocess
    import sys

    code = (f"import sys, {module}; "
            f"print(' '.join(m for m in {must_not_load!r} if m in sys.modules))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True, cwd=ROOT)
    assert done.stdout.strip() == "", f"importing {module} loaded {done.stdout.strip()}"
