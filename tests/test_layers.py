"""The package's layers: every import points down, no circle, no private name taken from another package.

Layers, top to bottom (docs in DEVELOPERS.md): cli > analysis > verification > run > plot > io > timestepping
> fem > model > scene, with `errors`, `jitlog`, `signals` and `stack` below them all. The top-level
`stringcontact` (the public API, loaded lazily) may be imported by analysis and cli only. Every import counts, those
inside functions too.
"""

import ast
from pathlib import Path

import pytest

import stringcontact

LAYERS = ("scene", "model", "fem", "timestepping", "core", "io", "plot", "run", "verification", "analysis", "cli")
BASE = ("errors", "jitlog", "signals", "stack")
ROOT = Path(stringcontact.__file__).parent
FACADE_USERS = ("analysis", "cli")


def _module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    parts = parts[:-1] if parts[-1] == "__init__" else parts
    return ".".join(("stringcontact", *parts))


def _imports(path: Path, source: str | None = None):
    """(imported module, imported names) for each import of stringcontact code in `path` (or `source` as if there)."""
    name = _module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text() if source is None else source)):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            if module.split(".")[0] != "stringcontact":
                continue
            for alias in node.names:  # `from pkg import module` imports the module
                sub = f"{module}.{alias.name}"
                yield (sub, ()) if (ROOT.parent / sub.replace(".", "/")).with_suffix(".py").exists() or (
                    ROOT.parent / sub.replace(".", "/")).is_dir() else (module, (alias.name,))
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == "stringcontact":
                    yield alias.name, ()


def _layer(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "stringcontact"


def _rank(layer: str) -> int:
    if layer in BASE:
        return -1
    if layer in LAYERS:
        return LAYERS.index(layer)
    return LAYERS.index("run") if layer == "stringcontact" else 99  # the facade imports run (lazily)


SOURCES = sorted(p for p in ROOT.rglob("*.py") if "__pycache__" not in p.parts)
PACKAGED = [p for p in SOURCES if _layer(_module_name(p)) in LAYERS]


def test_every_module_belongs_to_a_layer():
    loose = [str(p.relative_to(ROOT)) for p in SOURCES if p.parent == ROOT and p.stem not in (*BASE, "__init__", "__main__")]
    assert loose == []
    assert {p.relative_to(ROOT).parts[0] for p in PACKAGED} == set(LAYERS)


def violations(path: Path, source: str | None = None) -> list[str]:
    """The imports of `path` that point up, use the facade from below, or take a private name from another package."""
    own, found = _layer(_module_name(path)), []
    where = path.relative_to(ROOT)
    for module, names in _imports(path, source):
        layer = _layer(module)
        if layer == own:
            continue
        if layer == "stringcontact":
            if own not in FACADE_USERS:
                found.append(f"{where} imports the top-level package")
            continue
        if _rank(layer) >= _rank(own):
            found.append(f"{where} imports {module}: {layer} is not below {own}")
        private = [n for n in (*names, module.rpartition(".")[2]) if n.startswith("_") and not n.startswith("__")]
        if private:
            found.append(f"{where} imports private {private} from {module}")
    return found


@pytest.mark.parametrize("path", PACKAGED, ids=lambda p: str(p.relative_to(ROOT)))
def test_imports_point_down_and_take_no_private_names(path):
    assert violations(path) == []


def test_no_import_circle_between_modules():
    known = {_module_name(p): p for p in SOURCES}
    graph = {name: set() for name in known}
    for name, path in known.items():
        for module, _ in _imports(path):
            while module not in known and "." in module:
                module = module.rpartition(".")[0]
            if module != name and module != "stringcontact":
                graph[name].add(module)
    # a package's __init__ importing its own modules is not a circle through them
    for name in list(graph):
        graph[name] = {m for m in graph[name] if not m.startswith(name + ".")}
    state, stack = {}, []

    def visit(node):
        state[node] = "open"
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == "open":
                raise AssertionError("import circle: " + " -> ".join(stack[stack.index(nxt):] + [nxt]))
            if nxt not in state:
                visit(nxt)
        stack.pop()
        state[node] = "done"

    for node in sorted(graph):
        if node not in state:
            visit(node)


def test_the_checker_catches_an_upward_and_a_private_import():
    """The rules above can fail: a scene module importing the driver, a cli module taking a private name."""
    scene = ROOT / "scene" / "data.py"
    assert violations(scene, "from ..run.driver import simulate\n") == [
        "scene/data.py imports stringcontact.run.driver: run is not below scene"]
    assert violations(scene, "import stringcontact as sc\n") == ["scene/data.py imports the top-level package"]
    cli = ROOT / "cli" / "main.py"
    assert violations(cli, "from ..run.driver import _march\n") == [
        "cli/main.py imports private ['_march'] from stringcontact.run.driver"]
    assert violations(cli, "from ..run.driver import simulate\n") == []


CORE = ("scene", "fem", "timestepping", "core", "io", "plot", "run")


def _declared_words() -> dict[str, str]:
    """Each shipped model that declares constants or output fields: its name, its constants' and fields' names
    (longer than one letter), word -> the model that owns it. Constants are matched as written (`Mu`, a matrix
    in newmark, is not the film's `mu`), model and field names in any case."""
    from stringcontact.model.interface import output_fields
    from stringcontact.model.registry import load_model
    from stringcontact.scene.names import package_of, registered

    words = {}
    for name, (ep,) in registered().items():
        model = load_model(name)
        if package_of(ep) != "stringcontact" or not (model.constants or output_fields(model)):
            continue
        words.update({f"(?i:{word})": name for word in (name, *(f.name for f in output_fields(model)))})
        words.update({c.name: name for c in model.constants if len(c.name) > 1})
    return words


def test_the_core_names_no_particular_model():
    """A model reaches the core through the interface every user model has: no core module names a shipped
    model with its own constants or fields, nor those constants and fields (whole words)."""
    import re

    words = _declared_words()
    assert {"(?i:film)", "mu", "(?i:pressure)"} <= set(words)  # the film declares them: the check can fail
    patterns = {re.compile(rf"\b{word}\b"): owner for word, owner in words.items()}
    found = []
    for layer in CORE:
        for path in sorted((ROOT / layer).rglob("*.py")):
            for number, line in enumerate(path.read_text().splitlines(), 1):
                found += [f"{path.relative_to(ROOT)}:{number}: {m.group(0)} ({owner})"
                          for pattern, owner in patterns.items() for m in pattern.finditer(line)]
    assert not found, "\n".join(found)


@pytest.mark.parametrize("module", ["stringcontact", "stringcontact.scene", "stringcontact.model.interface"])
def test_the_lower_layers_load_no_dolfinx_at_run_time(module):
    """The import rules checked where they matter: importing the package, a scene's layer or the model contract in a
    fresh process loads neither dolfinx nor PETSc nor a time scheme."""
    import subprocess
    import sys

    code = (f"import sys, {module}\n"
            "print(sorted(m for m in ('dolfinx', 'petsc4py', 'stringcontact.timestepping') if m in sys.modules))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]", out
