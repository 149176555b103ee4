"""benchmarks/: every script has its row (its question) in the benchmarks README, and no two scripts import each
other, directly or round a longer circle (what they share lives in `peers.py` and `rod.py`, which import none)."""

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
BENCHMARKS = ROOT / "benchmarks"
SCRIPTS = sorted(BENCHMARKS.glob("*.py"))


def test_every_benchmark_has_its_row_in_the_readme():
    listed = set(re.findall(r"^\| `([\w.]+\.py)`", (BENCHMARKS / "README.md").read_text(), flags=re.MULTILINE))
    assert SCRIPTS, "no benchmark found"
    assert {p.name for p in SCRIPTS} == listed


def _siblings(path: Path) -> set[str]:
    """The benchmark scripts `path` imports (anywhere in it, functions included)."""
    names = {p.stem for p in SCRIPTS}
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            found |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.add(node.module.split(".")[0])
    return (found & names) - {path.stem}


def test_no_benchmark_imports_another_in_a_circle():
    graph = {p.stem: _siblings(p) for p in SCRIPTS}
    circles = []
    for start, imported in graph.items():
        seen, todo = set(), list(imported)
        while todo:
            name = todo.pop()
            if name == start:
                circles.append(start)
                break
            if name not in seen:
                seen.add(name)
                todo.extend(graph[name])
    assert circles == [], {name: sorted(graph[name]) for name in circles}
