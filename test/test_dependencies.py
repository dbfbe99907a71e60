"""Dependencies run one way: the package's import graph, read from its source with ``ast``.

Every ``import`` of a ``pdsmc_ros`` module counts, wherever it stands: at the top of a module,
inside a function (a lazy import runs as soon as the function does, so it ties the modules as
firmly; deferring it only hides the circle from the interpreter) and under ``if TYPE_CHECKING:``
(a module that needs another's types to be read depends on it: the controller's action server
reads the node through a Protocol of its own for that reason). An edge goes to the module
named: ``from ..control.registry import law`` to ``pdsmc_ros.control.registry``,
``from . import python_form`` to that submodule, ``from ..control import GAINS`` to the package
``pdsmc_ros.control``; the parents a Python import also runs (``pdsmc_ros.control/__init__``) are no
edge of their own, or every package re-exporting its modules would be a circle.

Held: no import circle beyond the known ones (:data:`KNOWN_CIRCLES`, each to be removed; a new
circle, or a known one grown, fails); every module imports only its own layer or the layers
below it (:data:`LAYERS`, lowest first: the foundation modules directly under the package, the
kernels, the model maths, the parameter tables, the run, the simulation, the bags and
experiments, the ROS plumbing, the components, the command line), so nothing imports the
command line and the shared plumbing (:data:`PLUMBING`) imports no component; the maths
(:data:`MATHS`) and the components' ROS-free decisions (:data:`ROS_FREE`) import no ROS; a
module inside a function imports nothing that imports it back (a lazy import may defer a
cost, never hide a circle).
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "pdsmc_ros"

KNOWN_CIRCLES: set[frozenset[str]] = set()
"""Import circles that still exist, each a set of modules (a strongly connected component)."""

KNOWN_UPWARD: set[tuple[str, str]] = set()
"""Imports against the direction still in the package, each (importer, imported)."""

MATHS = ("kernels", "control", "robots", "contours", "metrics", "sim", "identification")
"""The ROS-free maths."""
COMPONENTS = ("controller", "plant", "trajectory", "recorder", "mujoco_driver", "viewer", "composed")
"""The ROS components, each its ROS-free decisions and its node."""
PLUMBING = ("parameters", "runs", "ros", "loop", "bag", "sim", "control", "robots", "contours", "metrics", "kernels")
"""What the components share: none of it imports a component (as ros2_control's hardware interfaces
and controller manager include no controller) or the command line."""
LAYERS: tuple[tuple[str, ...], ...] = (
    ("",),  # the foundation: errors, checks, config, resources, plugins, glibc, arguments
    ("kernels",),  # numba's cache and compile options
    ("robots", "contours", "control", "metrics"),  # the model maths
    ("parameters",),  # the one source of settings: the tables, params files, their rclpy declaration
    ("runs",),  # the run: RunSpec, the one builder, defaults from the tables
    ("sim",),  # simulation: the plant step, the closed loop, whole runs, the parallel engine
    ("bag", "experiments", "identification"),  # bags; experiments over runs; the model from a run
    ("ros", "loop"),  # the ROS plumbing: topics, publishers, the nodes' start-up, the loop
    COMPONENTS,
    ("cli",),  # the commands
)
"""The layers, lowest first: a module imports its own layer or lower ones only."""
MODULE_LAYER = {"pdsmc_ros.kernels.precompile": "cli"}
"""Modules whose layer is not their folder's: precompile is a command (``make setup`` runs it)
that compiles the kernels by running every robot and law through a run."""
ROS_LAYER = (*COMPONENTS, "loop", "ros", "parameters")
"""The components and the plumbing they share (the loop, topics and publishers, parameters)."""
ROS_FREE = tuple(f"pdsmc_ros.controller.{m}" for m in ("core", "commanding", "goals", "joint_trajectory", "hold",
                                                       "joints", "limits",
                                                       "sidecar.framing", "sidecar.process", "sidecar.gain_check")) + (
    "pdsmc_ros.parameters.joint_map",
    "pdsmc_ros.trajectory.reference_windows", "pdsmc_ros.loop.realtime", "pdsmc_ros.loop.statistics",
    "pdsmc_ros.loop.rt_check", "pdsmc_ros.viewer.live_view")
"""The components' ROS-free decisions, testable without ROS (the nodes beside them wire them)."""
ROS_MODULES = ("rclpy", "rosidl_runtime_py", "builtin_interfaces", "std_msgs", "sensor_msgs", "trajectory_msgs",
               "control_msgs", "diagnostic_msgs", "rosgraph_msgs", "lifecycle_msgs", "rcl_interfaces",
               "visualization_msgs", "geometry_msgs", "tf2_msgs", "action_msgs")


def module_names() -> dict[str, Path]:
    """Every module of the package by dotted name (a package by its own name)."""
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(ROOT).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = path
    return out


MODULES = module_names()


def imports(name: str, path: Path) -> Iterator[tuple[str, int]]:
    """``(imported name, line)`` of every import statement in the module's source, anywhere in it."""
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        yield from imports_of(name, path, node)


def imports_of(name: str, path: Path, node: ast.AST) -> Iterator[tuple[str, int]]:
    """``(imported name, line)`` of one import statement (nothing for another node)."""
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    if isinstance(node, ast.Import):
        for alias in node.names:
            yield alias.name, node.lineno
    elif isinstance(node, ast.ImportFrom):
        if node.level:
            base = ".".join(package[: len(package) - node.level + 1] + ([node.module] if node.module else []))
        else:
            base = node.module or ""
        for alias in node.names:
            yield f"{base}.{alias.name}" if f"{base}.{alias.name}" in MODULES else base, node.lineno


def owning_module(name: str) -> str | None:
    """The package module ``name`` is (or is in): ``pdsmc_ros.a.b.Thing`` -> ``pdsmc_ros.a.b``."""
    while name and name not in MODULES:
        name = name.rpartition(".")[0]
    return name or None


def graph() -> dict[str, dict[str, int]]:
    """Module -> the package modules it imports (with the line of the first such import)."""
    edges: dict[str, dict[str, int]] = {}
    for name, path in MODULES.items():
        edges[name] = {}
        for imported, line in imports(name, path):
            target = owning_module(imported) if imported.startswith("pdsmc_ros") else None
            if target is not None and target != name:
                edges[name].setdefault(target, line)
    return edges


def circles(edges: dict[str, dict[str, int]]) -> list[frozenset[str]]:
    """The strongly connected components of more than one module (Tarjan's algorithm, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []
    for root in edges:
        if root in index:
            continue
        work = [(root, iter(edges[root]))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(edges[child])))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = set()
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.add(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(frozenset(component))
    return found


def describe(component: frozenset[str], edges: dict[str, dict[str, int]]) -> str:
    lines = [f"  {a} -> {b} (line {edges[a][b]})" for a in sorted(component) for b in sorted(edges[a])
             if b in component]
    return "\n".join(lines)


def folder(module: str) -> str:
    """``pdsmc_ros.control.laws`` -> ``control``; a module directly under the package -> ``""``."""
    if module in MODULE_LAYER:
        return MODULE_LAYER[module]
    parts = module.split(".")
    return parts[1] if len(parts) > 2 or f"{module}.__init__" in MODULES or (PACKAGE / parts[-1]).is_dir() else ""


def rank(module: str) -> int:
    """The layer of ``module`` (its index in :data:`LAYERS`)."""
    name = folder(module)
    return next(i for i, names in enumerate(LAYERS) if name in names)


EDGES = graph()


def test_the_walk_sees_the_package_and_its_lazy_and_type_only_imports() -> None:
    """The graph is the package's: the known modules and edges, including a function's import and
    one under TYPE_CHECKING (a walk that missed them would pass every other test here)."""
    assert len(MODULES) > 150 and "pdsmc_ros.control.registry" in MODULES and "pdsmc_ros" in MODULES
    assert "pdsmc_ros.control.registry" in EDGES["pdsmc_ros.control.laws"]
    assert "pdsmc_ros.control.python_form" in EDGES["pdsmc_ros.control.law"]  # from . import python_form
    assert "pdsmc_ros.control.law_run" in EDGES["pdsmc_ros.control.law"]  # under TYPE_CHECKING
    assert "pdsmc_ros.robots.registry" in EDGES["pdsmc_ros.robots.urdf"]  # inside a function
    assert circles({"a": {"b": 1}, "b": {"c": 1}, "c": {"a": 1}, "d": {"a": 1}}) == [frozenset("abc")]
    assert circles({"a": {"b": 1}, "b": {}}) == []


def test_no_import_circle_beyond_the_known_ones() -> None:
    found = circles(EDGES)
    new = [c for c in found if c not in KNOWN_CIRCLES]
    assert not new, "import circles:\n" + "\n\n".join(describe(c, EDGES) for c in new)


@pytest.mark.parametrize("known", sorted(KNOWN_CIRCLES, key=sorted), ids=lambda c: " <-> ".join(sorted(c)))
def test_a_known_circle_still_exists_until_its_entry_is_removed(known: frozenset[str]) -> None:
    """An entry of :data:`KNOWN_CIRCLES` whose circle is gone fails: remove the entry (the list only shrinks)."""
    assert known in circles(EDGES), f"the circle {sorted(known)} is gone: remove it from KNOWN_CIRCLES"


def upward_imports() -> list[tuple[str, str, int, str]]:
    """``(importer, imported, line, rule)`` of every import against the direction."""
    out = []
    for module, targets in EDGES.items():
        if module == "pdsmc_ros":
            continue
        for target, line in targets.items():
            if target == "pdsmc_ros":
                continue  # the package's own __init__: __version__
            if folder(target) == "cli" and folder(module) != "cli":
                out.append((module, target, line, "nothing imports the command line"))
            elif folder(module) in PLUMBING and folder(target) in COMPONENTS:
                out.append((module, target, line, "plumbing imports no component"))
            elif rank(target) > rank(module):
                rule = f"layer {folder(module) or 'foundation'!r} imports the higher layer {folder(target)!r}"
                out.append((module, target, line, rule))
    return out


def test_no_module_imports_a_layer_above_its_own() -> None:
    wrong = [w for w in upward_imports() if (w[0], w[1]) not in KNOWN_UPWARD]
    assert not wrong, "imports against the direction:\n" + "\n".join(
        f"  {m} -> {t} (line {line}): {rule}" for m, t, line, rule in wrong)


@pytest.mark.parametrize("known", sorted(KNOWN_UPWARD), ids=lambda k: f"{k[0]} -> {k[1]}")
def test_a_known_upward_import_still_exists_until_its_entry_is_removed(known: tuple[str, str]) -> None:
    assert known in {(m, t) for m, t, _, _ in upward_imports()}, f"{known} is gone: remove it from KNOWN_UPWARD"


def test_the_maths_and_the_components_decisions_never_import_ros() -> None:
    wrong = []
    for module, path in MODULES.items():
        if folder(module) in MATHS or module in ROS_FREE:
            wrong += [f"  {module} imports {name} (line {line})" for name, line in imports(module, path)
                      if name.split(".")[0] in ROS_MODULES]
    assert not wrong, "the maths imports ROS:\n" + "\n".join(wrong)


def lazy_imports() -> list[tuple[str, str, int]]:
    """``(importer, imported, line)`` of every import of a package module made inside a function."""
    out = []
    for name, path in MODULES.items():
        tree = ast.parse(path.read_text(), str(path))
        for func in ast.walk(tree):
            if not isinstance(func, ast.FunctionDef | ast.AsyncFunctionDef):
                continue
            for node in ast.walk(func):
                if isinstance(node, ast.Import | ast.ImportFrom):
                    for imported, line in imports_of(name, path, node):
                        target = owning_module(imported) if imported.startswith("pdsmc_ros") else None
                        if target is not None and target != name:
                            out.append((name, target, line))
    return out


def reaches(start: str, goal: str) -> bool:
    """``start`` imports ``goal``, directly or through other modules (the graph's edges)."""
    seen, todo = {start}, [start]
    while todo:
        for nxt in EDGES[todo.pop()]:
            if nxt == goal:
                return True
            if nxt not in seen:
                seen.add(nxt)
                todo.append(nxt)
    return False


def test_no_lazy_import_hides_a_circle() -> None:
    """A function's import of a module that imports the importer back is a circle the interpreter
    does not see (the thesis arms once imported ``urdf.py`` so, which imported ``robots/`` back)."""
    hidden = [f"  {m} -> {t} (line {line})" for m, t, line in lazy_imports() if reaches(t, m)]
    assert not hidden, "lazy imports hiding a circle:\n" + "\n".join(hidden)


def test_the_layer_rules_catch_what_they_name() -> None:
    """The rules on examples: plumbing reaching into a component and the maths into the run are caught."""
    assert folder("pdsmc_ros.errors") == "" and folder("pdsmc_ros.runs.builder") == "runs"
    assert rank("pdsmc_ros.parameters.tables") < rank("pdsmc_ros.runs.builder") < rank("pdsmc_ros.sim.simulator")
    assert rank("pdsmc_ros.controller.core") > rank("pdsmc_ros.loop.serve")
    assert rank("pdsmc_ros.kernels.precompile") == rank("pdsmc_ros.cli.simulate")
