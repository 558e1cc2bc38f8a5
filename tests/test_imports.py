"""The package's import structure: every module imports on its own, and no two modules
import each other, directly or around a circle (function-level imports included)."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pedmesh

ROOT = Path(pedmesh.__file__).resolve().parent


def _modules() -> dict[str, Path]:
    mods = {}
    for p in sorted(ROOT.rglob("*.py")):
        parts = ["pedmesh", *p.relative_to(ROOT).with_suffix("").parts]
        if parts[-1] == "__init__":
            parts = parts[:-1]
        mods[".".join(parts)] = p
    return mods


def _import_graph() -> dict[str, set[str]]:
    """Module -> the pedmesh modules it imports anywhere in its text."""
    mods = _modules()
    graph: dict[str, set[str]] = {}
    for name, path in mods.items():
        package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
        deps: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package[:len(package) - (node.level - 1)]
                    target = ".".join(base + ([node.module] if node.module else []))
                else:
                    target = node.module or ""
                for alias in node.names:
                    full = f"{target}.{alias.name}"
                    if full in mods:
                        deps.add(full)
                    elif target in mods:
                        deps.add(target)
            elif isinstance(node, ast.Import):
                deps.update(a.name for a in node.names if a.name in mods)
        graph[name] = deps - {name}
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []
    counter = [0]

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
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
                out.append(sorted(comp))

    for v in graph:
        if v not in index:
            visit(v)
    return out


def test_the_cycle_finder_finds_a_cycle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_import_circles():
    graph = _import_graph()
    assert "pedmesh.run.driver" in graph and graph["pedmesh.run.driver"]
    assert _cycles(graph) == []


def test_every_module_imports_on_its_own():
    """Each module imported first, in one fresh interpreter with pedmesh's modules dropped
    from sys.modules before each (third-party packages stay loaded, for speed)."""
    names = sorted(n for n in _modules() if not n.endswith("__main__"))  # that one runs
    code = (
        "import importlib, sys\n"
        f"for name in {names!r}:\n"
        "    for m in [m for m in sys.modules if m == 'pedmesh' or m.startswith('pedmesh.')]:\n"
        "        del sys.modules[m]\n"
        "    try:\n"
        "        importlib.import_module(name)\n"
        "    except Exception as exc:\n"
        "        print(f'{name}: {type(exc).__name__}: {exc}')\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stdout == ""


#: the package's layers, bottom first: a module may import its own layer and those below,
#: never one above (a module belongs to the longest prefix that names it)
LAYERS: list[tuple[str, ...]] = [
    ("pedmesh.errors", "pedmesh._version", "pedmesh._signals", "pedmesh._threads",
     "pedmesh._arrays"),
    ("pedmesh.parameters",),
    ("pedmesh.speed", "pedmesh.population"),
    ("pedmesh.presets",),
    ("pedmesh.geometry",),
    ("pedmesh.mesh",),
    ("pedmesh.eikonal", "pedmesh.io"),
    ("pedmesh.analysis",),
    ("pedmesh.models",),
    ("pedmesh.run",),
    ("pedmesh.api", "pedmesh.animate", "pedmesh.report", "pedmesh.compare",
     "pedmesh.ensembles", "pedmesh.calibration", "pedmesh.validation", "pedmesh.plotting",
     "pedmesh.fitting", "pedmesh._browser"),
    ("pedmesh.cli", "pedmesh.__main__", "pedmesh"),
]


def _layer(module: str) -> int:
    best, layer = -1, None
    for i, prefixes in enumerate(LAYERS):
        for p in prefixes:
            if (module == p or module.startswith(p + ".")) and len(p) > best:
                best, layer = len(p), i
    assert layer is not None, f"{module} is in no layer: add it to LAYERS"
    return layer


def test_the_layer_check_sees_an_upward_import():
    assert _layer("pedmesh.geometry.room") < _layer("pedmesh.mesh.triangulate")
    assert _layer("pedmesh.models.sfm.adapter") == _layer("pedmesh.models")
    assert _layer("pedmesh") > _layer("pedmesh.run.driver")


def test_imports_point_down_the_layers():
    """No import runs back up a layer (function-level imports included)."""
    graph = _import_graph()
    up = sorted(f"{a} -> {b}" for a, deps in graph.items() for b in deps
                if _layer(b) > _layer(a))
    assert up == []


def test_the_two_scales_stand_side_by_side():
    """The social force model and the continuum models do not import each other."""
    graph = _import_graph()
    sides = ("pedmesh.models.sfm", "pedmesh.models.continuum")
    cross = sorted(f"{a} -> {b}" for a, deps in graph.items() for b in deps
                   for i, s in enumerate(sides)
                   if a.startswith(s) and b.startswith(sides[1 - i]))
    assert cross == []


def test_one_model_registry():
    """Every model (both scales) is one entry of pedmesh.models' registry."""
    from pedmesh.models import entries, get_model
    from pedmesh.models.continuum.adapter import ContinuumEntry

    names = {e.name for e in entries()}
    assert {"sfm", "eos", "rdue", "pw", "mac1"} <= names
    assert get_model("sf").name == "sfm" and get_model("hughes").name == "rdue"
    assert isinstance(get_model("eos"), ContinuumEntry)
    assert get_model("sfm").scale == "particles" and get_model("eos").scale == "continuum"


def test_no_module_named_like_a_dependency_or_a_sibling():
    """No module shadows a dependency's name, no two files differ only by an underscore, and
    module is named like one of pedmesh's packages."""
    deps = {"trimesh", "triangle", "shapely", "meshio", "pyvista", "numba", "numpy", "scipy",
            "matplotlib", "ezdxf", "tqdm", "dask", "pandas", "pedpy", "pytest", "hypothesis",
            "skfmm", "sphinx"}
    mods = _modules()
    stems = [n.rsplit(".", 1)[-1] for n, p in mods.items() if p.name != "__init__.py"]
    packages = {p.parent.name for p in mods.values() if p.name == "__init__.py"}
    assert sorted(set(stems) & deps) == []
    for name, path in mods.items():
        if path.name == "__init__.py":
            continue
        siblings = {p.stem for p in path.parent.glob("*.py")}
        assert path.stem.lstrip("_") == path.stem or path.stem.lstrip("_") not in siblings, name
        assert path.stem not in packages, f"{name}: a module named like a package"
