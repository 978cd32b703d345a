"""The house's layering: gaits < tuner helpers < servos < robots < sim < scenarios, challenge < search < report < identify < cli.

Every import of a project module counts, at the top of a file or inside a function (a lazy
import runs upward just the same). Package ``__init__`` files are faces that re-export their
rooms and are left out of the graph.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
WINGS = {"store": 1.5, "servos": 1.7, "robots": 2, "sim": 3, "scenarios": 3.5, "challenge": 3.5, "search": 4, "report": 5, "identify": 5.5}


def wing(module: str) -> int:
    """0 gaits, 1 tuner's top-level helpers, 2-5 the wings, 6 the CLI."""
    parts = module.split(".")
    if parts[0] == "gaits":
        return 0
    if len(parts) == 1:
        return 1
    if parts[1] == "cli":
        return 6
    return WINGS.get(parts[1], 1)


def _modules() -> dict[str, Path]:
    out = {}
    for top in ("gaits", "tuner"):
        for path in sorted((ROOT / top).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts)] = path
    return out


def import_graph() -> dict[str, set[str]]:
    """module -> the project modules it imports (faces left out)."""
    mods = _modules()
    faces = {m for m, p in mods.items() if p.name == "__init__.py"}
    graph: dict[str, set[str]] = {}
    for mod, path in mods.items():
        if mod in faces:
            continue
        package = mod.split(".")[:-1]
        targets: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names: list[str] = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = (node.module or "") if node.level == 0 else ".".join(
                    package[:len(package) - node.level + 1] + ([node.module] if node.module else []))
                names = [base] + [f"{base}.{a.name}" for a in node.names]
            for name in names:
                while name and name not in mods:
                    name = name.rpartition(".")[0]
                if name and name != mod and name not in faces:
                    targets.add(name)
        graph[mod] = targets
    return graph


def test_no_import_runs_from_a_lower_wing_to_a_higher_one():
    upward = [f"{a} ({wing(a)}) imports {b} ({wing(b)})" for a, bs in import_graph().items() for b in bs
              if wing(b) > wing(a)]
    assert upward == []


def test_no_import_cycle():
    graph = import_graph()
    cycles, state = [], {}

    def visit(node: str, path: list[str]) -> None:
        state[node] = "open"
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == "open":
                cycles.append(" -> ".join(path[path.index(nxt):] + [nxt]))
            elif nxt not in state:
                visit(nxt, path + [nxt])
        state[node] = "done"
    for node in sorted(graph):
        if node not in state:
            visit(node, [node])
    assert cycles == []


def test_the_checker_sees_a_lazy_upward_import(tmp_path, monkeypatch):
    """The test itself can fail: a function-level import from sim into search is found."""
    fake = tmp_path / "tuner" / "sim"
    fake.mkdir(parents=True)
    (tmp_path / "gaits").mkdir()
    (tmp_path / "tuner" / "search").mkdir()
    (tmp_path / "tuner" / "search" / "study.py").write_text("X = 1\n")
    (fake / "loop.py").write_text("def f():\n    from ..search.study import X\n    return X\n")
    monkeypatch.setattr(__import__(__name__), "ROOT", tmp_path)
    assert import_graph()["tuner.sim.loop"] == {"tuner.search.study"}
