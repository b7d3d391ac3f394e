"""Fail on an import cycle among the modules of the given packages (default: glpma_ros and glpma_tools).

The graph is read from the source (nothing is imported): a module depends on every module it names in an
``import`` or ``from ... import`` statement anywhere in its file, inside functions too (an import put into a
function hides a cycle from the interpreter, not from the design), except under ``if TYPE_CHECKING:``.
``from package import name`` depends on the submodule ``package.name`` when there is one, else on the
package's ``__init__``.  The packages a submodule sits in are not counted as its dependencies (Python runs
their ``__init__`` first, but they import nothing back unless they say so, and then that is an edge).
Every strongly connected component of more than one module is a cycle; each is printed with one path
around it.  Exit status 1 when there is one, 0 otherwise.

    python tools/check_import_cycles.py [--root DIR] [PACKAGE ...]
"""
from __future__ import annotations

import argparse
import ast
import sys
from pathlib import Path


def modules(root: Path, packages) -> dict:
    """Dotted name -> (path, is_package) of every module of ``packages`` under ``root``."""
    found = {}
    for package in packages:
        for path in sorted((root / package).rglob("*.py")):
            parts = list(path.relative_to(root).with_suffix("").parts)
            is_package = parts[-1] == "__init__"
            if is_package:
                parts.pop()
            found[".".join(parts)] = (path, is_package)
    return found


def _type_checking_only(node, parents) -> bool:
    while node in parents:
        node = parents[node]
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            return True
    return False


def dependencies(name: str, path: Path, is_package: bool, known: dict) -> set:
    """The modules of ``known`` that module ``name`` imports."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    parents = {child: node for node in ast.walk(tree) for child in ast.iter_child_nodes(node)}
    package = name if is_package else name.rpartition(".")[0]
    deps = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base_parts = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                base = ".".join(base_parts + ([node.module] if node.module else []))
            else:
                base = node.module
            targets = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in known else base for alias in node.names]
        else:
            continue
        if _type_checking_only(node, parents):
            continue
        for target in targets:
            while target and target not in known:       # ``import a.b.c`` of a name inside a.b.c: the module
                target = target.rpartition(".")[0]
            if target and target != name:
                deps.add(target)
    return deps


def graph(root: Path, packages) -> dict:
    known = modules(root, packages)
    return {name: dependencies(name, path, is_package, known) for name, (path, is_package) in known.items()}


def cycles(edges: dict) -> list:
    """The strongly connected components of more than one module (Tarjan's algorithm, iterative)."""
    index, low, on_stack, stack, found = {}, {}, set(), [], []
    counter = 0
    for start in sorted(edges):
        if start in index:
            continue
        work = [(start, iter(sorted(edges[start])))]
        index[start] = low[start] = counter
        counter += 1
        stack.append(start)
        on_stack.add(start)
        while work:
            node, successors = work[-1]
            for succ in successors:
                if succ not in index:
                    index[succ] = low[succ] = counter
                    counter += 1
                    stack.append(succ)
                    on_stack.add(succ)
                    work.append((succ, iter(sorted(edges.get(succ, ())))))
                    break
                if succ in on_stack:
                    low[node] = min(low[node], index[succ])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    component = []
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        component.append(member)
                        if member == node:
                            break
                    if len(component) > 1:
                        found.append(sorted(component))
    return sorted(found)


def path_around(component, edges) -> list:
    """One cycle through the component's first module (breadth-first, inside the component)."""
    members = set(component)
    start = component[0]
    previous = {start: None}
    queue = [start]
    for node in queue:
        for succ in sorted(edges[node] & members):
            if succ == start:
                chain = [node]
                while previous[chain[-1]] is not None:
                    chain.append(previous[chain[-1]])
                return [*reversed(chain), start]
            if succ not in previous:
                previous[succ] = node
                queue.append(succ)
    return component


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("packages", nargs="*", default=["glpma_ros", "glpma_tools"])
    parser.add_argument("--root", type=Path, default=Path(__file__).resolve().parent.parent)
    args = parser.parse_args(argv)
    edges = graph(args.root, args.packages)
    found = cycles(edges)
    for component in found:
        print(f"import cycle among {len(component)} modules: {' -> '.join(path_around(component, edges))}")
        print(f"  all of them: {', '.join(component)}")
    if not found:
        print(f"no import cycle among the {len(edges)} modules of {', '.join(args.packages)}")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
