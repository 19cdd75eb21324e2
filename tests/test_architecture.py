"""The floors the code is built on, read from the source's imports (every ``import`` and
``from ... import``, those inside functions too, since a lazy import is still a dependency):

- the protocol (``pac_protocol``) imports neither the host nor the simulator;
- the simulator (``pac_sim``) may use the host's model but never its CLI;
- the host reaches the simulator through one module only (the built-in emulator's connector);
- no two of the host's subpackages (or top-level modules) import each other, however
  indirectly;
- each shared constant and each tracker line has one home.

The checker is tested on small made-up sources too, so a violation would really be caught.
"""

from __future__ import annotations

import ast
from collections.abc import Iterable, Mapping
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = {
    "pac_host": ROOT / "host" / "pac_host",
    "pac_protocol": ROOT / "protocol" / "pac_protocol",
    "pac_sim": ROOT / "simulator" / "pac_sim",
}
ONE_WAY_IN = {"pac_host.robot.emulator"}  # the host's one importer of pac_sim
SHARED_CONSTANTS = ("MAX_GENES", "BLOCK_CM", "START_POSE", "POWER_ON_MOD")


# ---- the checker -------------------------------------------------------------------------------


def module_name(package: str, root: Path, path: Path) -> str:
    parts = [package, *path.relative_to(root).with_suffix("").parts]
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports_of(source: str, module: str, is_package: bool) -> set[str]:
    """Every module name ``source`` imports, anywhere in it; for ``from M import n`` both M
    and M.n (n may be a submodule), relative imports resolved against ``module``."""
    out: set[str] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = module.split(".") if is_package else module.split(".")[:-1]
                base = base[:len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            out.add(target)
            out.update(f"{target}.{a.name}" for a in node.names if a.name != "*")
    return out


def import_graph(packages: Mapping[str, Path]) -> dict[str, set[str]]:
    """Each module of ``packages`` -> the names it imports that lie in those packages."""
    graph: dict[str, set[str]] = {}
    for package, root in packages.items():
        for path in sorted(root.rglob("*.py")):
            name = module_name(package, root, path)
            found = imports_of(path.read_text(), name, path.name == "__init__.py")
            graph[name] = {t for t in found if t.split(".")[0] in packages}
    return graph


def importers(graph: Mapping[str, set[str]], source: str, target: str) -> dict[str, list[str]]:
    """The modules of package ``source`` that import anything of ``target`` (a package or a
    dotted prefix), with what they import."""
    def under(name: str, prefix: str) -> bool:
        return name == prefix or name.startswith(prefix + ".")

    return {m: sorted(t for t in ts if under(t, target)) for m, ts in graph.items()
            if under(m, source) and any(under(t, target) for t in ts)}


def node_of(module: str, depth: int = 2) -> str:
    """The node a module belongs to: ``pac_host.robot.api`` -> ``pac_host.robot``."""
    return ".".join(module.split(".")[:depth])


def node_graph(graph: Mapping[str, set[str]], package: str) -> dict[str, set[str]]:
    """The modules of ``package`` folded into its subpackages and top-level modules."""
    out: dict[str, set[str]] = {}
    for m, ts in graph.items():
        if node_of(m, 1) != package:
            continue
        a = node_of(m)
        out.setdefault(a, set())
        for t in ts:
            if node_of(t, 1) == package and node_of(t) != a:
                out[a].add(node_of(t))
    return out


def cycles(graph: Mapping[str, Iterable[str]]) -> list[list[str]]:
    """The strongly connected components with more than one node (Tarjan): each holds a
    cycle."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(found)


def why(graph: Mapping[str, set[str]], comp: list[str]) -> list[str]:
    """The imports that tie a component's nodes together (for the failure message)."""
    return sorted(f"{m} -> {t}" for m, ts in graph.items() for t in ts
                  if node_of(m) in comp and node_of(t) in comp and node_of(t) != node_of(m))


def module_level_names(source: str) -> set[str]:
    """The names a module assigns at its top level (a definition, not an import)."""
    names: set[str] = set()
    for node in ast.parse(source).body:
        targets = node.targets if isinstance(node, ast.Assign) else (
            [node.target] if isinstance(node, ast.AnnAssign) else [])
        for t in targets:
            for n in ast.walk(t):
                if isinstance(n, ast.Name):
                    names.add(n.id)
    return names


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    return import_graph(PACKAGES)


# ---- the project's floors ----------------------------------------------------------------------


def test_the_walk_sees_every_package_and_lazy_imports(graph):
    assert {"pac_host.cli.main", "pac_protocol.link", "pac_sim.runner",
            "pac_host.robot.emulator"} <= set(graph)
    # imports inside functions count: the emulator opens pac_sim only when asked to
    assert "pac_sim.runner" in graph["pac_host.robot.emulator"]


def test_the_protocol_imports_neither_the_host_nor_the_simulator(graph):
    assert importers(graph, "pac_protocol", "pac_host") == {}
    assert importers(graph, "pac_protocol", "pac_sim") == {}


def test_the_simulator_never_imports_the_host_cli(graph):
    assert importers(graph, "pac_sim", "pac_host.cli") == {}


def test_the_host_reaches_the_simulator_in_one_module(graph):
    assert set(importers(graph, "pac_host", "pac_sim")) == ONE_WAY_IN


def test_no_import_cycle_between_the_hosts_subpackages(graph):
    nodes = node_graph(graph, "pac_host")
    assert {"pac_host.camera", "pac_host.robot", "pac_host.cli", "pac_host.errors"} <= set(nodes)
    found = cycles(nodes)
    assert found == [], "\n".join(f"{c}: {why(graph, c)}" for c in found)


def test_each_shared_constant_is_defined_once():
    homes: dict[str, list[str]] = {c: [] for c in SHARED_CONSTANTS}
    for package, root in PACKAGES.items():
        for path in sorted(root.rglob("*.py")):
            defined = module_level_names(path.read_text())
            for c in SHARED_CONSTANTS:
                if c in defined:
                    homes[c].append(module_name(package, root, path))
    assert {c: len(ms) for c, ms in homes.items()} == dict.fromkeys(SHARED_CONSTANTS, 1), homes


def test_the_tracker_lines_are_written_in_one_module():
    """A ``POSE``/``PLACE``/``PLACED`` line is built only by pac_protocol.tracker_line."""
    writers = set()
    for package, root in PACKAGES.items():
        for path in sorted(root.rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, ast.JoinedStr) and node.values and isinstance(
                        node.values[0], ast.Constant) and str(node.values[0].value).startswith(
                        ("POSE ", "PLACE ", "PLACED ")):
                    writers.add(module_name(package, root, path))
    assert writers == {"pac_protocol.tracker_line"}


# ---- the checker catches what it must ----------------------------------------------------------


def test_the_checker_finds_a_cycle_and_only_a_cycle():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": {"c"}, "c": set(), "d": {"a", "c"}}) == []
    assert cycles({"a": {"b"}, "b": {"a"}, "c": {"d"}, "d": {"c"}}) == [["a", "b"], ["c", "d"]]


def test_the_checker_reads_lazy_relative_and_from_imports(tmp_path):
    """A made-up host whose camera imports its robot inside a function, and whose protocol
    imports the host: both are seen, and the subpackages fold into one cycle."""
    host, proto = tmp_path / "pac_host", tmp_path / "pac_protocol"
    for d in (host / "camera", host / "robot", proto):
        d.mkdir(parents=True)
        (d / "__init__.py").write_text("")
    (host / "camera" / "observer.py").write_text(
        "def open_camera():\n    from pac_host.robot import observers\n")
    (host / "robot" / "observers.py").write_text("from ..camera.observer import open_camera\n")
    (host / "robot" / "api.py").write_text("from . import observers\n")
    (proto / "link.py").write_text("import pac_host.robot.api\n")
    g = import_graph({"pac_host": host, "pac_protocol": proto})
    assert g["pac_host.camera.observer"] == {"pac_host.robot", "pac_host.robot.observers"}
    assert "pac_host.camera.observer" in g["pac_host.robot.observers"]
    assert "pac_host.robot.observers" in g["pac_host.robot.api"]
    assert set(importers(g, "pac_protocol", "pac_host")) == {"pac_protocol.link"}
    assert cycles(node_graph(g, "pac_host")) == [["pac_host.camera", "pac_host.robot"]]


def test_a_second_definition_is_seen():
    assert "MAX_GENES" in module_level_names("MAX_GENES = 9\n")
    assert "BLOCK_CM" in module_level_names("BLOCK_CM: float = 60.0\n")
    assert "START_POSE" not in module_level_names("from x import START_POSE\n"
                                                  "def f():\n    START_POSE = 1\n")
