"""Module and function size figures of the package (issue 32's before / after table).

``.venv/bin/python tools/code_size.py [PACKAGE_DIR] [--json FILE]``: modules directly in the
package, files per sub-package, modules over 600 lines, functions over 80 and of 90+ lines
(the longest listed), total lines. Counts physical lines, as ``wc -l`` does.
"""

from __future__ import annotations

import argparse
import ast
import json
from pathlib import Path


def figures(root: Path) -> dict:
    mods = sorted(p for p in root.rglob("*.py") if "__pycache__" not in p.parts)
    lines = {p: len(p.read_text(encoding="utf-8").splitlines()) for p in mods}
    funcs = []
    for p in mods:
        for node in ast.walk(ast.parse(p.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                funcs.append((node.end_lineno - node.lineno + 1,
                              f"{p.relative_to(root.parent).as_posix()}:{node.name}"))
    funcs.sort(reverse=True)
    subs = {d.name: len([p for p in mods if p.parent == d])
            for d in sorted(root.iterdir()) if d.is_dir() and d.name != "__pycache__"}
    return {
        "modules": len(mods),
        "top_level_modules": len([p for p in mods if p.parent == root]),
        "files_per_subpackage": subs,
        "modules_over_600_lines": sorted(
            [[n, p.relative_to(root.parent).as_posix()] for p, n in lines.items() if n > 600],
            reverse=True),
        "functions_over_80_lines": len([f for f in funcs if f[0] > 80]),
        "functions_of_90_plus_lines": len([f for f in funcs if f[0] >= 90]),
        "longest_functions": [list(f) for f in funcs[:10]],
        "total_lines": sum(lines.values()),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("package", nargs="?", default="warerover_phys", type=Path)
    ap.add_argument("--json", type=Path, help="also write the figures here")
    args = ap.parse_args()
    fig = figures(args.package)
    print(f"modules {fig['modules']} ({fig['top_level_modules']} at the top level), "
          f"{fig['total_lines']} lines")
    print("files per sub-package: " + ", ".join(f"{k} {v}" for k, v in
                                                fig["files_per_subpackage"].items()))
    print(f"modules over 600 lines: {len(fig['modules_over_600_lines'])}")
    for n, p in fig["modules_over_600_lines"]:
        print(f"  {n:5d}  {p}")
    print(f"functions over 80 lines: {fig['functions_over_80_lines']}, "
          f"of 90+ lines: {fig['functions_of_90_plus_lines']}")
    for n, name in fig["longest_functions"]:
        print(f"  {n:5d}  {name}")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(fig, indent=1))


if __name__ == "__main__":
    main()
