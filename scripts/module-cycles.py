#!/usr/bin/env python3
"""Circular imports between the top-level modules of each workspace crate (issue 28, 6).

A module is a crate root's `mod NAME;` with everything under it (NAME.rs, NAME/...). Module A
depends on B when code in A (test modules left out) names `crate::B`, or a name the crate
root re-exports from B (`pub use B::Thing;` and `crate::Thing`). Strongly connected groups of
more than one module are cycles: the layers of the crate no longer read top to bottom.

    scripts/module-cycles.py [--allowed FILE] [WORKSPACE]

Prints each cycle as `CRATE: A <-> B <-> C`. With --allowed, the cycles listed in FILE (same
form, `#` comments) are known and tolerated while they are being removed; the exit status is
1 if a cycle is not listed (a new one, or a known one grown) or a listed one is gone (take it
off the list), else 0.
"""
import argparse
import json
import os
import re
import subprocess
import sys


def targets(workspace):
    meta = json.loads(
        subprocess.check_output(
            ["cargo", "metadata", "--no-deps", "--format-version", "1", "--offline"],
            cwd=workspace,
        )
    )
    for package in meta["packages"]:
        for target in package["targets"]:
            if {"lib", "bin"} & set(target["kind"]):
                yield package["name"], target["src_path"]


def without_comments(text):
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    return re.sub(r"//[^\n]*", "", text)


def without_tests(text):
    """The file up to its test module (by this codebase's rule, the last item)."""
    found = re.search(r"^#\[cfg\(test\)\]\s*\n\s*(?:pub(?:\([^)]*\))?\s+)?mod \w+\s*\{", text, re.M)
    return text[: found.start()] if found else text


def modules(root_file):
    """Top-level module name -> its files."""
    here = os.path.dirname(root_file)
    text = without_comments(open(root_file).read())
    found = {}
    for name in re.findall(r"^\s*(?:pub(?:\([^)]*\))?\s+)?mod\s+(\w+)\s*;", text, re.M):
        files = [p for p in (os.path.join(here, name + ".rs"),) if os.path.exists(p)]
        for dirpath, _, names in os.walk(os.path.join(here, name)):
            files += [os.path.join(dirpath, n) for n in sorted(names) if n.endswith(".rs")]
        found[name] = files
    return found


def reexports(root_file, names):
    """Names the crate root re-exports -> the module they come from."""
    text = without_comments(open(root_file).read())
    origin = {}
    for use in re.finditer(r"pub use\s+(?:self::|crate::)?(\w+)::([^;]+);", text, re.S):
        module, items = use.group(1), use.group(2)
        if module in names:
            for item in re.findall(r"\b([A-Za-z_]\w*)\b(?!\s*::)", items):
                if item not in ("as", "self", "super", "crate"):
                    origin[item] = module
    return origin


def dependencies(mods, origin):
    graph = {name: set() for name in mods}
    for name, files in mods.items():
        for path in files:
            text = without_comments(without_tests(open(path).read()))
            used = set(re.findall(r"\bcrate::(\w+)", text))
            for group in re.findall(r"\bcrate::\{([^}]*)\}", text, re.S):
                used |= set(re.findall(r"\b(\w+)\b", group))
            for word in used:
                other = word if word in mods else origin.get(word)
                if other and other != name:
                    graph[name].add(other)
    return graph


def cycles(graph):
    """Tarjan's strongly connected components of more than one module, sorted."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(node):
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for other in sorted(graph[node]):
            if other not in index:
                visit(other)
                low[node] = min(low[node], low[other])
            elif other in on_stack:
                low[node] = min(low[node], index[other])
        if low[node] == index[node]:
            group = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                group.append(member)
                if member == node:
                    break
            if len(group) > 1:
                found.append(" <-> ".join(sorted(group)))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return sorted(found)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--allowed", help="a file of known cycles, one `CRATE: A <-> B` a line")
    parser.add_argument("workspace", nargs="?", default=".")
    args = parser.parse_args()
    sys.setrecursionlimit(10_000)
    found = set()
    for crate, root_file in targets(args.workspace):
        mods = modules(root_file)
        for cycle in cycles(dependencies(mods, reexports(root_file, mods))):
            found.add(f"{crate}: {cycle}")
    for line in sorted(found):
        print(line)
    print(f"{len(found)} cycles")
    if not args.allowed:
        return 0
    allowed = set()
    with open(args.allowed) as listed:
        for line in listed:
            line = line.split("#", 1)[0].strip()
            if line:
                allowed.add(line)
    status = 0
    for line in sorted(found - allowed):
        print(f"module-cycles: new cycle (break it; see ARCHITECTURE.md): {line}", file=sys.stderr)
        status = 1
    for line in sorted(allowed - found):
        print(f"module-cycles: gone, take it off {args.allowed}: {line}", file=sys.stderr)
        status = 1
    return status


if __name__ == "__main__":
    sys.exit(main())
