"""The import graph of rodlab's own modules has no cycle, and no arrow points up the layers.

The graph is read statically with ``ast``: every ``import`` / ``from ... import`` of a project module counts,
wherever it stands (module level, inside a function, under ``if TYPE_CHECKING:``), relative imports are resolved,
and ``from pkg import name`` points at ``pkg.name`` when that is a submodule (else at ``pkg``). Layers, bottom up:
``sim`` <- ``policies`` <- ``workbench`` (docs/architecture.md); ``benchmarks``, ``tools`` and ``rodlab_cli`` sit
on top. Function-level imports are for heavy optional libraries only; one that names a project module is counted
here like any other, so it cannot hide a cycle.
"""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("sim", "policies", "workbench", "benchmarks", "tools")
SINGLE_MODULES = ("rodlab_cli",)
# A module may not import from a package listed against its own top-level package.
FORBIDDEN_UP = {"sim": {"policies", "workbench", "benchmarks", "tools", "rodlab_cli"},
                "policies": {"workbench", "benchmarks", "tools", "rodlab_cli"},
                "workbench": {"benchmarks", "tools", "rodlab_cli"}}


def project_modules(root: Path = ROOT) -> dict[str, Path]:
    """Dotted module name -> file, for every .py file of the project's packages (and the single modules)."""
    mods: dict[str, Path] = {}
    for pkg in PACKAGES:
        for path in sorted((root / pkg).rglob("*.py")):
            parts = list(path.relative_to(root).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            mods[".".join(parts)] = path
    for name in SINGLE_MODULES:
        mods[name] = root / f"{name}.py"
    return mods


def _target(name: str, mods: dict[str, Path]) -> str | None:
    """The project module a dotted name refers to: itself, or the nearest enclosing module that exists."""
    parts = name.split(".")
    while parts:
        cand = ".".join(parts)
        if cand in mods:
            return cand
        parts.pop()
    return None


def imports_of(module: str, path: Path, mods: dict[str, Path]) -> list[tuple[str, int, bool]]:
    """(imported project module, line, at module level) for every import statement in the file."""
    tree = ast.parse(path.read_text(), filename=str(path))
    is_pkg = path.name == "__init__.py"
    top_level = {id(node) for node in tree.body}
    for node in tree.body:  # `if TYPE_CHECKING:` / try blocks at module level are still module level
        if isinstance(node, (ast.If, ast.Try)):
            top_level.update(id(n) for n in ast.walk(node) if isinstance(n, (ast.Import, ast.ImportFrom)))
    out: list[tuple[str, int, bool]] = []
    for node in tree.body:  # a package's lazy public face (PEP 562): `_LAZY = {name: "module", ...}` imports those
        if (is_pkg and isinstance(node, ast.Assign) and any(getattr(t, "id", "") == "_LAZY" for t in node.targets)
                and isinstance(node.value, ast.Dict)):
            for value in node.value.values:
                tgt = _target(value.value, mods) if isinstance(value, ast.Constant) else None
                if tgt is not None and tgt != module:
                    out.append((tgt, value.lineno, True))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = module.split(".") if is_pkg else module.split(".")[:-1]
                base = base[:len(base) - (node.level - 1)]
                pkg = ".".join(base + ([node.module] if node.module else []))
            else:
                pkg = node.module or ""
            names = [f"{pkg}.{alias.name}" if f"{pkg}.{alias.name}" in mods else pkg for alias in node.names]
        else:
            continue
        for name in names:
            tgt = _target(name, mods)
            if tgt is not None and tgt != module:
                out.append((tgt, node.lineno, id(node) in top_level))
    return out


def import_graph(root: Path = ROOT) -> dict[str, dict[str, int]]:
    """module -> {imported module: line of the first such import}."""
    mods = project_modules(root)
    graph: dict[str, dict[str, int]] = {}
    for mod, path in mods.items():
        edges: dict[str, int] = {}
        for tgt, line, _ in imports_of(mod, path, mods):
            edges.setdefault(tgt, line)
        graph[mod] = edges
    return graph


def function_level_imports(root: Path = ROOT) -> list[str]:
    """'module:line -> target' for every import of a project module that is not at module level."""
    mods = project_modules(root)
    return [f"{mod}:{line} -> {tgt}" for mod, path in mods.items() for tgt, line, top in imports_of(mod, path, mods)
            if not top]


def strongly_connected(graph: dict[str, dict[str, int]]) -> list[list[str]]:
    """Tarjan's strongly connected components with more than one module (each sorted), iteratively."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    comps: list[list[str]] = []
    counter = 0
    for start in sorted(graph):
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = counter
        counter += 1
        stack.append(start)
        on_stack.add(start)
        while work:
            node, it = work[-1]
            for nxt in it:
                if nxt not in index:
                    index[nxt] = low[nxt] = counter
                    counter += 1
                    stack.append(nxt)
                    on_stack.add(nxt)
                    work.append((nxt, iter(sorted(graph[nxt]))))
                    break
                if nxt in on_stack:
                    low[node] = min(low[node], index[nxt])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    comp = []
                    while True:
                        m = stack.pop()
                        on_stack.discard(m)
                        comp.append(m)
                        if m == node:
                            break
                    if len(comp) > 1:
                        comps.append(sorted(comp))
    return sorted(comps)


def cycle_path(graph: dict[str, dict[str, int]], comp: list[str]) -> str:
    """One cycle inside a strongly connected component, as 'a:line -> b:line -> ... -> a'."""
    members = set(comp)
    start = comp[0]
    # breadth-first from start's successors back to start, inside the component
    prev: dict[str, str] = {}
    frontier = [start]
    seen = {start}
    found = None
    while frontier and found is None:
        nxt_frontier = []
        for node in frontier:
            for nxt in sorted(graph[node]):
                if nxt not in members:
                    continue
                if nxt == start:
                    found = node
                    break
                if nxt not in seen:
                    seen.add(nxt)
                    prev[nxt] = node
                    nxt_frontier.append(nxt)
            if found is not None:
                break
        frontier = nxt_frontier
    path = [found]
    while path[-1] != start:
        path.append(prev[path[-1]])
    path.reverse()
    path.append(start)
    return " -> ".join(f"{a} (line {graph[a][b]})" for a, b in zip(path, path[1:])) + f" -> {start}"


def test_graph_sees_project_imports():
    graph = import_graph()
    assert "policies.learning.training" in graph["policies.learning"]  # a lazy face's `_LAZY` entries are imports
    assert "sim.scene" in graph["sim"] and "sim.step" in graph["sim"]
    assert "policies.tasks.registry" in graph["policies.vec_env"]  # relative `from .tasks.registry import ...`
    assert "policies.vec_env" in graph["policies.tasks"]  # inside a function (gymnasium's vector entry point)
    assert "sim.support.atomicio" in graph["policies.recording.export"]  # `from sim.support import atomicio`: a submodule


def test_import_graph_has_no_cycle():
    graph = import_graph()
    comps = strongly_connected(graph)
    msg = "\n".join(f"cycle among {', '.join(c)}:\n    {cycle_path(graph, c)}" for c in comps)
    assert not comps, f"{len(comps)} import cycle(s):\n{msg}"


def test_no_import_points_up_the_layers():
    bad = [f"{mod} (line {line}) imports {tgt}" for mod, edges in import_graph().items()
           for tgt, line in edges.items() if tgt.split(".")[0] in FORBIDDEN_UP.get(mod.split(".")[0], ())]
    assert not bad, "imports against the layering sim <- policies <- workbench:\n" + "\n".join(bad)


def test_support_is_the_bottom_layer():
    """sim.support (atomic files, progress, path checks) imports nothing else of rodlab: every package may use it."""
    bad = [f"{mod} (line {line}) imports {tgt}" for mod, edges in import_graph().items() if mod.startswith("sim.support")
           for tgt, line in edges.items() if not tgt.startswith("sim.support")]
    assert not bad, "\n".join(bad)


def test_cycle_finder_reports_a_path(tmp_path):
    (tmp_path / "sim").mkdir()
    for pkg in PACKAGES[1:]:
        (tmp_path / pkg).mkdir()
    (tmp_path / "rodlab_cli.py").write_text("")
    (tmp_path / "sim" / "__init__.py").write_text("")
    (tmp_path / "sim" / "a.py").write_text("from . import b\n")
    (tmp_path / "sim" / "b.py").write_text("def f():\n    from sim.c import x\n    return x\n")
    (tmp_path / "sim" / "c.py").write_text("from .a import y\n")
    graph = import_graph(tmp_path)
    comps = strongly_connected(graph)
    assert comps == [["sim.a", "sim.b", "sim.c"]]
    assert cycle_path(graph, comps[0]) == "sim.a (line 1) -> sim.b (line 2) -> sim.c (line 1) -> sim.a"
    assert function_level_imports(tmp_path) == ["sim.b:2 -> sim.c"]


if __name__ == "__main__":  # report: the cycles and the function-level project imports
    g = import_graph()
    for c in strongly_connected(g):
        print("cycle:", ", ".join(c), "\n   ", cycle_path(g, c))
    fl = function_level_imports()
    print(len(fl), "function-level imports of project modules")
    for line in fl:
        print("  ", line)


# Public faces: code outside a face's scope imports the face (its __init__), never a module behind it. The scope is
# the package whose own modules may still import those modules directly (sim's kernels import sim.geometry.vec3).
FACES = {"policies.learning": "policies.learning", "policies.recording": "policies.recording",
         "workbench.session": "workbench.session", "workbench.view": "workbench.view",
         "workbench.panels": "workbench.panels", "workbench.serve": "workbench.serve",
         "sim": "sim", "sim.scene": "sim", "sim.geometry": "sim", "sim.analysis": "sim", "sim.contact": "sim",
         "sim.kernels": "sim", "sim.energies": "sim"}
# modules anyone may import: the support layer's helpers, one module each (sim/support/__init__.py)
OPEN = ("sim.support",)


def _inside(mod: str, pkg: str) -> bool:
    return mod == pkg or mod.startswith(pkg + ".")


def face_violations(graph: dict[str, dict[str, int]]) -> list[str]:
    """'importer (line) imports module: use the face' for every import of a module behind a face from outside its
    scope. A target that is itself a face (or under OPEN) is fine."""
    bad = []
    for mod, edges in graph.items():
        for tgt, line in edges.items():
            if tgt in FACES or any(_inside(tgt, o) for o in OPEN):
                continue
            faces = [f for f in FACES if tgt.startswith(f + ".")]
            if not faces:
                continue
            face = max(faces, key=len)  # the nearest face in front of the module
            if not _inside(mod, FACES[face]):
                bad.append(f"{mod} (line {line}) imports {tgt}: use `from {face} import ...`")
    return bad


def test_packages_are_used_through_their_public_face():
    bad = face_violations(import_graph())
    assert not bad, "\n".join(bad)


def test_face_rule_sees_a_private_import():
    graph = {"workbench.view.scene": {"workbench.session.frame": 3, "workbench.session": 4},
             "policies.vec_env": {"sim.step": 7, "sim": 8, "sim.support.atomicio": 9, "sim.scene": 10},
             "sim.kernels.batch": {"sim.geometry.vec3": 5}}
    assert face_violations(graph) == [
        "workbench.view.scene (line 3) imports workbench.session.frame: use `from workbench.session import ...`",
        "policies.vec_env (line 7) imports sim.step: use `from sim import ...`"]


# a package's roles, bottom up: a module may import its own role and the ones below it, never one above
ROLES = {"workbench": ("session", "view", "panels", "serve")}


def test_roles_inside_a_package_point_one_way():
    def role(mod: str) -> tuple[str, int] | None:
        parts = mod.split(".")
        order = ROLES.get(parts[0])
        return (parts[0], order.index(parts[1])) if order and len(parts) > 1 and parts[1] in order else None

    bad = []
    for mod, edges in import_graph().items():
        own = role(mod)
        for tgt, line in edges.items():
            other = role(tgt)
            if own and other and own[0] == other[0] and other[1] > own[1]:
                order = ROLES[own[0]]
                bad.append(f"{mod} (line {line}) imports {tgt}: {order[own[1]]} sits below {order[other[1]]}")
    assert not bad, "\n".join(bad)
