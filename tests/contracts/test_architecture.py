"""The layer map of docs/architecture.md, checked on the import graph.

Every import counts: module level, under ``TYPE_CHECKING`` and inside functions. A module may
import its own layer or a lower one, and a package only its own floor or lower ones (the floors
order the packages inside each layer too); ``sgjax`` never imports ``train``; there is no
import circle inside ``sgjax/``.
"""

from __future__ import annotations

import ast
import functools
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

# Lowest first: each layer is a list of packages (and the few leaf modules) that make it up; a
# module belongs to the layer of the longest prefix that contains it. A module under no prefix
# fails the test (place every new module in a layer's package).
LAYERS: dict[str, tuple[str, ...]] = {
    "kernels": ("sgjax.version", "sgjax.validation", "sgjax.files", "sgjax.kernels", "sgjax.maps",
                "sgjax.dynamics", "sgjax.humans"),
    "types": ("sgjax.types",),
    "terms": ("sgjax.terms", "sgjax.observations", "sgjax.rewards"),
    "environment": ("sgjax.environment", "sgjax"),
    "evaluation": ("sgjax.evaluation",),
    "applications": ("sgjax.adapters", "sgjax.editor", "sgjax.command",
                     "sgjax.compilation_cache"),
}
# Every package (and top-level module) of sgjax/ as a floor, lowest first: an import from one
# floor to another must point down this list, inside a layer as well as across layers (within
# a floor anything goes, bar circles).
FLOORS: tuple[str, ...] = (
    "sgjax.version", "sgjax.validation", "sgjax.files", "sgjax.kernels", "sgjax.maps",
    "sgjax.dynamics", "sgjax.humans", "sgjax.types", "sgjax.terms", "sgjax.observations",
    "sgjax.rewards", "sgjax.environment", "sgjax", "sgjax.evaluation", "sgjax.compilation_cache",
    "sgjax.adapters", "sgjax.editor", "sgjax.command")
# The trainer's wings, lowest first: the algorithm (config, networks, actor, rollout, losses,
# GAE, learner, trainer), the run machinery (the training loop, partial files, phases,
# checkpoints, processes, sweep spaces, config conversion), the reports, and the experiment
# commands at the top of train/ (cli, reproduce, ablation, sweep).
TRAIN_FLOORS: tuple[str, ...] = ("train.algorithm", "train.run", "train.reports", "train")
# Modules that sit directly in sgjax/ (the rest live in the layer packages).
TOP_LEVEL_MODULES = {"sgjax.version", "sgjax.validation", "sgjax.files", "sgjax.types",
                     "sgjax.command",
                     "sgjax.compilation_cache"}
# The longest function allowed in sgjax/ (lines from ``def`` to its last line), and the ones
# allowed to be longer, with the reason.
MAX_FUNCTION_LINES = 80
LONG_FUNCTIONS: dict[str, str] = {
    "sgjax.dynamics.planner:plan": (
        "the local planner's hot path: one straight data flow (arcs, clearances, scores, the "
        "chosen command) whose intermediate [R, A] arrays XLA fuses; split into functions it "
        "would read the same arrays through more names and no shorter"),
}


def modules(package: str) -> dict[str, Path]:
    """Dotted module name -> file, for every module of ``package``."""
    out = {}
    for path in sorted((ROOT / package).rglob("*.py")):
        parts = path.relative_to(ROOT).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = path
    return out


def imported(name: str, path: Path, known: set[str]) -> set[str]:
    """Project modules that ``name`` imports anywhere in its file (``from a import b`` counts
    module ``a.b`` when it is one, else ``a``)."""
    targets = set()
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            candidates = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                base = ".".join(anchor + ([base] if base else []))
            candidates = [f"{base}.{alias.name}" for alias in node.names] + [base]
        else:
            continue
        for candidate in candidates:
            while candidate and candidate not in known:
                candidate = candidate.rpartition(".")[0]
            if candidate and candidate != name:
                targets.add(candidate)
                break
    return targets


@functools.cache
def import_graph() -> dict[str, set[str]]:
    found = modules("sgjax") | modules("train")
    return {name: imported(name, path, set(found)) for name, path in found.items()}


def layer_of(name: str) -> int:
    best, index = "", -1
    for i, prefixes in enumerate(LAYERS.values()):
        for prefix in prefixes:
            inside = name == prefix or (prefix != "sgjax" and name.startswith(prefix + "."))
            if inside and len(prefix) > len(best):
                best, index = prefix, i
    return index


def floor_of(name: str, floors: tuple[str, ...] = FLOORS) -> int:
    """The index in ``floors`` of the longest floor holding module ``name`` (-1: none)."""
    best, index = "", -1
    for i, floor in enumerate(floors):
        inside = name == floor or (floor != "sgjax" and name.startswith(floor + "."))
        if inside and len(floor) > len(best):
            best, index = floor, i
    return index


def upward_edges(graph: dict[str, set[str]], floors: tuple[str, ...]) -> list[str]:
    """``"a -> b (floor A -> floor B)"`` for every import from a floor to a higher one."""
    found = []
    for name in sorted(graph):
        for target in sorted(graph[name]):
            low, high = floor_of(name, floors), floor_of(target, floors)
            if low >= 0 and high > low:
                found.append(f"{name} -> {target} ({floors[low]} -> {floors[high]})")
    return found


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
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
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_cycle_finder_sees_a_circle():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


def test_import_finder_reads_local_and_type_checking_imports(tmp_path):
    source = ("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from p.b import X\n"
              "def f():\n    from p import c\n    import p.d.e\n")
    path = tmp_path / "a.py"
    path.write_text(source)
    assert imported("p.a", path, {"p", "p.a", "p.b", "p.c", "p.d"}) == {"p.b", "p.c", "p.d"}


def test_no_import_circle_inside_sgjax():
    graph = {m: {t for t in ts if t.split(".")[0] == "sgjax"}
             for m, ts in import_graph().items() if m.split(".")[0] == "sgjax"}
    assert cycles(graph) == []


def test_sgjax_never_imports_train():
    edges = [(m, t) for m, ts in import_graph().items() if m.split(".")[0] == "sgjax"
             for t in ts if t.split(".")[0] == "train"]
    assert edges == []
    statement = re.compile(r"^\s*(import train\b|from train\b)", re.MULTILINE)
    dynamic = re.compile(r"import_module\(\s*[\"']train\b")
    text = [p.name for p in sorted((ROOT / "sgjax").rglob("*.py"))
            if statement.search(p.read_text()) or dynamic.search(p.read_text())]
    assert text == []


@pytest.mark.parametrize("name", sorted(modules("sgjax")))
def test_module_imports_only_its_layer_or_lower(name):
    assert layer_of(name) >= 0, f"{name} is in no layer: add it to LAYERS and the docs"
    graph = import_graph()
    upward = [t for t in sorted(graph[name]) if t.startswith("sgjax")
              and layer_of(t) > layer_of(name)]
    names = list(LAYERS)
    assert upward == [], (f"{name} ({names[layer_of(name)]}) imports a higher layer: "
                          + ", ".join(f"{t} ({names[layer_of(t)]})" for t in upward))


def test_floor_finder_sees_an_edge_up_a_layer():
    graph = {"p.low.a": {"p.high.b"}, "p.high.b": {"p.low.c"}, "p.low.c": set()}
    assert upward_edges(graph, ("p.low", "p.high")) == ["p.low.a -> p.high.b (p.low -> p.high)"]


def test_no_package_imports_a_higher_floor():
    """Package to package, every edge points down :data:`FLOORS` (the kernels' ``contacts``
    reads walls through a protocol, not ``maps``; the planner lives beside the robot dynamics;
    the term presets beside the environment that assembles terms)."""
    graph = {m: {t for t in ts if t.startswith("sgjax")} for m, ts in import_graph().items()
             if m.startswith("sgjax")}
    assert [m for m in sorted(graph) if floor_of(m) < 0] == [], "add the package to FLOORS"
    assert upward_edges(graph, FLOORS) == []
    # FLOORS refines LAYERS: a floor never sits below one of a lower layer
    layers = [layer_of(floor) for floor in FLOORS]
    assert layers == sorted(layers), list(zip(FLOORS, layers, strict=True))


def test_no_import_circle_inside_train_and_no_wing_imports_a_higher_one():
    graph = {m: {t for t in ts if t.split(".")[0] == "train"}
             for m, ts in import_graph().items() if m.split(".")[0] == "train"}
    assert cycles(graph) == []
    assert upward_edges(graph, TRAIN_FLOORS) == []
    top = {m for m, path in modules("train").items() if path.parent == ROOT / "train"}
    assert top == {"train", "train.__main__", "train.cli", "train.reproduce", "train.ablation",
                   "train.sweep", "train.transfer", "train.export", "train.tables"}, (
        "a module of train/ belongs in a wing")


def test_no_function_in_train_is_over_the_limit():
    found = {}
    for path in sorted((ROOT / "train").rglob("*.py")):
        found |= long_functions(path, MAX_FUNCTION_LINES)
    assert found == {}


def test_architecture_doc_names_every_layer_module():
    text = (ROOT / "docs" / "architecture.md").read_text()
    missing = [m for m in sorted(modules("sgjax")) if m != "sgjax" and "." in m
               and m.count(".") == 1 and f"{m.split('.')[1]}" not in text]
    assert missing == []


def test_layers_are_package_prefixes():
    """Every prefix in LAYERS is a package (a folder with ``__init__.py``) or one of the few
    top-level modules; the top level of ``sgjax/`` holds no other module."""
    for prefix in (p for prefixes in LAYERS.values() for p in prefixes):
        folder = ROOT / Path(*prefix.split("."))
        assert (folder / "__init__.py").exists() or prefix in TOP_LEVEL_MODULES, prefix
    top = {m for m, path in modules("sgjax").items()
           if path.parent == ROOT / "sgjax" and path.name != "__init__.py"}
    assert top == TOP_LEVEL_MODULES


def test_no_two_modules_share_a_file_name():
    by_name: dict[str, list[str]] = {}
    for path in sorted((ROOT / "sgjax").rglob("*.py")):
        if path.name not in ("__init__.py", "base.py"):
            by_name.setdefault(path.name, []).append(str(path.relative_to(ROOT)))
    assert {n: ps for n, ps in by_name.items() if len(ps) > 1} == {}


def long_functions(path: Path, limit: int) -> dict[str, int]:
    """``module:qualname`` -> lines, for every function or method in ``path`` over ``limit``."""
    inside = path.is_relative_to(ROOT)
    module = ".".join((path.relative_to(ROOT) if inside else Path(path.name)).with_suffix("").parts)
    found = {}

    def visit(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef):
                name = f"{prefix}{child.name}"
                lines = child.end_lineno - child.lineno + 1
                if lines > limit:
                    found[f"{module}:{name}"] = lines
                visit(child, f"{name}.")
            elif isinstance(child, ast.ClassDef):
                visit(child, f"{prefix}{child.name}.")

    visit(ast.parse(path.read_text(), str(path)), "")
    return found


def test_long_function_finder_counts_lines(tmp_path):
    path = tmp_path / "m.py"
    path.write_text("class A:\n    def f(self):\n" + "        x = 1\n" * 5 + "def g():\n    pass\n")
    found = long_functions(path, 4)
    assert list(found.values()) == [6] and next(iter(found)).endswith(":A.f")


def test_no_function_in_sgjax_is_over_the_limit():
    found = {}
    for path in sorted((ROOT / "sgjax").rglob("*.py")):
        found |= long_functions(path, MAX_FUNCTION_LINES)
    assert {name: n for name, n in found.items() if name not in LONG_FUNCTIONS} == {}


def test_importing_every_module_starts_no_xla_backend():
    """Importing sgjax and train computes nothing: ``jax.distributed.initialize`` (multi-process
    sweeps) must come before the first computation, so no module may build an array at import."""
    import subprocess
    import sys

    # JaxMARL (the library the adapter wraps) builds arrays when it is imported.
    third_party = {"sgjax.adapters.jaxmarl": "jaxmarl"}
    names = sorted(n for n in (modules("sgjax") | modules("train"))
                   if n not in ("train.__main__", *third_party))
    program = ("import importlib, jax._src.xla_bridge as xb\n"
               f"for name in {names!r}:\n"
               "    importlib.import_module(name)\n"
               "    assert not xb._backends, f'importing {name} started the XLA backend'\n")
    out = subprocess.run([sys.executable, "-c", program], capture_output=True, text=True,
                         cwd=ROOT, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]


def test_every_package_is_installed_by_pyproject():
    """``pyproject.toml`` lists its packages by name: a package folder missing from the list
    works in the editable install the suite uses and is absent from a wheel (``pip install .``:
    sgjax.evaluation.metrics was, and every command failed to import on a GPU machine)."""
    import tomllib

    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
                 ["packages"])
    found = {".".join(init.parent.relative_to(ROOT).parts)
             for top in ("sgjax", "train") for init in (ROOT / top).rglob("__init__.py")}
    assert found - listed == set(), f"pyproject.toml's packages lack {sorted(found - listed)}"
    assert listed - found <= {"sgjax.shipped_maps"}, sorted(listed - found)
