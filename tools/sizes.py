"""Module and function sizes of the package: what the house rules (issue 32) limit.

Prints the modules over ``--max-lines`` lines (600), the functions over ``--max-func`` lines
(80; a function's length is its ``def`` line to its last line, decorators and docstring
included), and how many modules sit directly in ``warerover_phys/``. ``--json`` prints one
JSON document instead of the tables.

    python tools/sizes.py [--json] [--root warerover_phys] [--max-lines 600] [--max-func 80]

Functions whose docstring says ``compiled kernel`` are listed apart (numba kernels whose length
their docstring justifies).
"""

from __future__ import annotations

import argparse
import ast
import json
import sys
from pathlib import Path


def measure(root: Path, max_lines: int, max_func: int) -> dict:
    modules, functions, kernels = [], [], []
    n_modules = 0
    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(root.parent).as_posix()
        text = path.read_text()
        n_modules += 1
        lines = len(text.splitlines())
        if lines > max_lines:
            modules.append({"module": rel, "lines": lines})
        for node in ast.walk(ast.parse(text)):
            if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            start = min([node.lineno] + [d.lineno for d in node.decorator_list])
            length = node.end_lineno - start + 1
            if length > max_func:
                row = {"module": rel, "function": node.name, "line": node.lineno,
                       "lines": length}
                doc = (ast.get_docstring(node) or "").lower()
                (kernels if "compiled kernel" in doc else functions).append(row)
    top = sorted(p.name for p in root.glob("*.py"))
    return {"root": root.as_posix(), "max_lines": max_lines, "max_function_lines": max_func,
            "modules": n_modules, "top_level_modules": len(top), "top_level": top,
            "long_modules": sorted(modules, key=lambda r: -r["lines"]),
            "long_functions": sorted(functions, key=lambda r: -r["lines"]),
            "long_kernels": sorted(kernels, key=lambda r: -r["lines"])}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--root", type=Path, default=Path(__file__).resolve().parents[1] / "warerover_phys")
    ap.add_argument("--max-lines", type=int, default=600)
    ap.add_argument("--max-func", type=int, default=80)
    ap.add_argument("--json", action="store_true", help="one JSON document on stdout")
    a = ap.parse_args(argv)
    if not a.root.is_dir():
        print(f"--root: {a.root}: not a folder", file=sys.stderr)
        return 2
    r = measure(a.root, a.max_lines, a.max_func)
    if a.json:
        print(json.dumps(r, indent=1))
        return 0
    print(f"{r['modules']} modules, {r['top_level_modules']} directly in {a.root.name}/")
    print(f"\nmodules over {a.max_lines} lines: {len(r['long_modules'])}")
    for m in r["long_modules"]:
        print(f"  {m['lines']:5d}  {m['module']}")
    print(f"\nfunctions over {a.max_func} lines: {len(r['long_functions'])}")
    for f in r["long_functions"]:
        print(f"  {f['lines']:5d}  {f['module']}:{f['line']} {f['function']}")
    if r["long_kernels"]:
        print(f"\ncompiled kernels over {a.max_func} lines (justified in their docstring): "
              f"{len(r['long_kernels'])}")
        for f in r["long_kernels"]:
            print(f"  {f['lines']:5d}  {f['module']}:{f['line']} {f['function']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
