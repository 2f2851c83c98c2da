#!/usr/bin/env python3
"""The crates' layering, from ARCHITECTURE.md, checked against `cargo metadata` (issue 28, 8).

ARCHITECTURE.md's diagram (its first fenced block) names every workspace crate under a layer,
top to bottom: apps, host, models, interface, core. A line starting with a word opens that
layer; `crates/DIR` names a crate by its directory. The rules:

1. every workspace crate is in the diagram, and every crate the diagram names exists;
2. a crate depends (normal dependencies: not dev, not build) only on crates of its own layer
   or below;
3. the crates listed in ENGINE_AND_BELOW (the one bus engine) depend on core crates only:
   the engine knows no particular model;
4. every path the document names in backquotes (`crates/...`, `docs/...`, with `{a,b}`
   alternatives) exists, so its "where each feature lives" table stays true.

    scripts/layering.py [--allowed FILE] [WORKSPACE]
    scripts/layering.py --self-test

Prints each breach as `FROM -> TO: rule`. With --allowed, the breaches listed in FILE (one
`FROM -> TO  # why` a line) are known and tolerated while they are being removed; the exit
status is 1 if a breach is not listed or a listed one is gone (take it off the list), else 0.
"""
import argparse
import itertools
import json
import os
import re
import subprocess
import sys

LAYERS = ["apps", "host", "models", "interface", "core"]
# Crates held to "core crates only" beyond the layer rule, and why.
ENGINE_AND_BELOW = {"buslab-sim": "the one bus engine knows no particular model"}


def diagram_layers(architecture):
    """Crate directory (`crates/NAME`) -> layer, from the first fenced block."""
    block = architecture.split("```", 2)[1]
    layers, layer = {}, None
    for line in block.splitlines():
        found = re.match(r"^(\w+)?\s+(crates/[\w-]+)", line)
        if not found:
            continue
        if found.group(1):
            if found.group(1) not in LAYERS:
                raise SystemExit(f"ARCHITECTURE.md: unknown layer {found.group(1)!r} "
                                 f"(known: {', '.join(LAYERS)})")
            layer = found.group(1)
        if layer is None:
            raise SystemExit(f"ARCHITECTURE.md: {found.group(2)} comes before any layer")
        layers[found.group(2)] = layer
    return layers


def workspace_packages(workspace):
    """Package name -> (crate directory relative to the workspace, [normal workspace deps])."""
    meta = json.loads(subprocess.check_output(
        ["cargo", "metadata", "--no-deps", "--format-version", "1", "--offline"],
        cwd=workspace))
    root = meta["workspace_root"]
    names = {p["name"] for p in meta["packages"]}
    packages = {}
    for p in meta["packages"]:
        directory = os.path.relpath(os.path.dirname(p["manifest_path"]), root)
        deps = sorted({d["name"] for d in p["dependencies"]
                       if d["name"] in names and d.get("kind") is None})
        packages[p["name"]] = (directory, deps)
    return packages


def breaches(layers, packages):
    """`FROM -> TO: rule` strings, and problems that no list can tolerate."""
    found, fatal = [], []
    by_dir = {directory: name for name, (directory, _) in packages.items()}
    for directory in sorted(set(layers) - set(by_dir)):
        fatal.append(f"ARCHITECTURE.md names {directory}, which is no workspace crate")
    layer_of = {}
    for name, (directory, _) in sorted(packages.items()):
        if directory not in layers:
            fatal.append(f"{name} ({directory}) is not in ARCHITECTURE.md's diagram")
        else:
            layer_of[name] = layers[directory]
    rank = {layer: i for i, layer in enumerate(LAYERS)}
    for name, (_, deps) in sorted(packages.items()):
        if name not in layer_of:
            continue
        for dep in deps:
            if dep not in layer_of:
                continue
            mine, theirs = layer_of[name], layer_of[dep]
            if rank[theirs] < rank[mine]:
                found.append(f"{name} -> {dep}: a {mine} crate depends on a {theirs} crate "
                             f"(dependencies point down only)")
            elif name in ENGINE_AND_BELOW and theirs != "core":
                found.append(f"{name} -> {dep}: {ENGINE_AND_BELOW[name]} "
                             f"(core crates only; {dep} is {theirs})")
    return found, fatal


def missing_paths(architecture, workspace):
    """Paths named in backquotes that do not exist."""
    missing = []
    pattern = r"`((?:crates|scripts|docs|bench|fuzz|examples|tests|scenarios)/[^`\s]*)`"
    for named in re.findall(pattern, architecture):
        parts = re.split(r"\{([^}]*)\}", named)
        options = [[p] if i % 2 == 0 else p.split(",") for i, p in enumerate(parts)]
        for combo in itertools.product(*options):
            path = "".join(combo)
            if "*" not in path and not os.path.exists(os.path.join(workspace, path)):
                missing.append(f"ARCHITECTURE.md names {path}, which does not exist")
    return sorted(set(missing))


def read_allowed(path):
    allowed = set()
    with open(path) as f:
        for line in f:
            line = line.split("#", 1)[0].strip()
            if line:
                allowed.add(re.sub(r"\s+", " ", line))
    return allowed


def judge(found, fatal, allowed):
    """Lines to print and the exit status."""
    lines, status = list(fatal), 1 if fatal else 0
    pairs = {b.split(":", 1)[0]: b for b in found}
    for pair, breach in sorted(pairs.items()):
        if allowed is not None and pair in allowed:
            lines.append(f"known: {breach}")
        else:
            lines.append(breach)
            status = 1
    for pair in sorted((allowed or set()) - set(pairs)):
        lines.append(f"{pair}: listed as allowed but no longer there; take it off the list")
        status = 1
    lines.append(f"{len(pairs)} layering breaches, {len(fatal)} diagram problems")
    return lines, status


def self_test():
    """The checker on a made-up workspace: it must find each kind of breach."""
    architecture = "x\n```\napps   crates/app\nhost   crates/h\nmodels crates/sim\n" \
                   "       crates/m\ncore   crates/c\n       crates/gone\n```\n"
    packages = {
        "app": ("crates/app", ["h", "c"]),
        "h": ("crates/h", ["m", "app"]),          # upward: host -> apps
        "buslab-sim": ("crates/sim", ["m", "c"]),  # the engine knows a model
        "m": ("crates/m", ["c"]),
        "c": ("crates/c", []),
        "stray": ("crates/stray", []),             # not in the diagram
    }
    found, fatal = breaches(diagram_layers(architecture), packages)
    assert sorted(b.split(":")[0] for b in found) == ["buslab-sim -> m", "h -> app"], found
    assert any("crates/gone" in f for f in fatal) and any("stray" in f for f in fatal), fatal
    lines, status = judge(found, [], {"h -> app", "x -> y"})
    assert status == 1 and any("x -> y" in l and "no longer there" in l for l in lines), lines
    lines, status = judge(found, [], {"h -> app", "buslab-sim -> m"})
    assert status == 0, lines
    lines, status = judge(found, [], None)
    assert status == 1, lines
    here = os.path.dirname(os.path.abspath(__file__))
    assert missing_paths("`scripts/{layering.py,nowhere.py}`", os.path.dirname(here)) == [
        "ARCHITECTURE.md names scripts/nowhere.py, which does not exist"]
    print("layering.py self-test: ok")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--allowed")
    ap.add_argument("--self-test", action="store_true")
    ap.add_argument("workspace", nargs="?", default=".")
    args = ap.parse_args()
    if args.self_test:
        self_test()
        return 0
    with open(os.path.join(args.workspace, "ARCHITECTURE.md")) as f:
        layers = diagram_layers(f.read())
    found, fatal = breaches(layers, workspace_packages(args.workspace))
    with open(os.path.join(args.workspace, "ARCHITECTURE.md")) as f:
        fatal += missing_paths(f.read(), args.workspace)
    allowed = read_allowed(args.allowed) if args.allowed else None
    lines, status = judge(found, fatal, allowed)
    print("\n".join(lines))
    return status


if __name__ == "__main__":
    sys.exit(main())
