"""How often one `stringcontact run example1 --out DIR` crosses from one module of the package into another.

    .venv/bin/python benchmarks/count_module_crossings.py                   # this tree
    .venv/bin/python benchmarks/count_module_crossings.py --src OTHER/src   # another checkout (e.g. an old commit)

A profiler hook (`sys.setprofile`) sees every Python call in this process while the CLI runs the paper's
Example 1 into a temporary folder, pictures included (drawn in the picture process, which is not counted).
A call crosses a module boundary when the caller's file and the callee's file are different modules of the
package; it crosses a package boundary when they lie in different subpackages (a flat module counts as its
own package). Prints the modules executed, the distinct crossings (caller → callee pairs) and the number of
crossing calls, for modules and for packages.
"""

from __future__ import annotations

import argparse
import collections
import importlib
import sys
import tempfile
from pathlib import Path


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--src", help="the src folder to import stringcontact from (default: the installed one)")
    ap.add_argument("--top", type=int, default=0, help="also list the N most frequent crossings")
    args = ap.parse_args()
    if args.src:
        sys.path.insert(0, str(Path(args.src).resolve()))
    package = Path(importlib.import_module("stringcontact").__file__).parent
    cli = importlib.import_module("stringcontact.cli")
    main_fn = getattr(cli, "main", None) or importlib.import_module("stringcontact.cli.main").main

    def module_of(filename: str) -> str | None:
        path = Path(filename)
        try:
            rel = path.resolve().relative_to(package)
        except ValueError:
            return None
        return ".".join(rel.with_suffix("").parts)

    calls = collections.Counter()
    executed = set()

    def hook(frame, event, arg):
        if event != "call":
            return
        callee = module_of(frame.f_code.co_filename)
        if callee is None:
            return
        executed.add(callee)
        caller = module_of(frame.f_back.f_code.co_filename) if frame.f_back else None
        if caller is not None and caller != callee:
            calls[(caller, callee)] += 1

    with tempfile.TemporaryDirectory() as tmp:
        sys.setprofile(hook)
        try:
            code = main_fn(["run", "example1", "--out", str(Path(tmp) / "ex1"), "--no-progress"])
        finally:
            sys.setprofile(None)
    packages = collections.Counter()
    for (a, b), n in calls.items():
        pa, pb = a.split(".")[0], b.split(".")[0]
        if pa != pb:
            packages[(pa, pb)] += n
    print(f"exit code {code}; package {package}")
    print(f"modules executed: {len(executed)}")
    print(f"module crossings: {len(calls)} distinct caller -> callee pairs, {sum(calls.values())} calls")
    print(f"package crossings: {len(packages)} distinct pairs, {sum(packages.values())} calls")
    for (a, b), n in calls.most_common(args.top):
        print(f"  {n:6d}  {a} -> {b}")


if __name__ == "__main__":
    main()
