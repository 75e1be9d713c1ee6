#!/usr/bin/env python3
"""layers.py - the layering test: no C file includes a header of a layer above its own.

Usage: python3 tests/layers.py [--table]
Exit 0 when every include points down or sideways, 1 with one line per offending include
(the file, its line, the header and both layers). --table prints files, lines and functions per
layer, and the include graph between layers (the figures ARCHITECTURE.md quotes).

The layers, bottom to top, are the Makefile's LAYERS (ARCHITECTURE.md says what each holds);
tools/ (gen_man.c) sits above them all. A header is found as the compiler finds it: beside the
including file first (renderers' "../renderer.h"), then by its name in the layer folders, which
is why a header name may live in one folder only (checked too). Two rules sharpen the picture:
the rasterizer (render/raster.[ch]) includes nothing above core/, so it stays ignorant of
models and BRDFs; and the formula layer's headers never include the scene's.
"""

import os
import re
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
LAYERS = ["core", "model", "scene", "render", "harness", "cli", "tools"]
# Files held to a lower ceiling than their folder's (reason in the docstring).
CEILING = {"render/raster.c": "core", "render/raster.h": "core"}
INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"')


def sources():
    for layer in LAYERS:
        for d, _, files in os.walk(os.path.join(ROOT, layer)):
            for f in sorted(files):
                if f.endswith((".c", ".h", ".cpp", ".def")):
                    yield os.path.relpath(os.path.join(d, f), ROOT)


def layer_of(path):
    return path.split(os.sep, 1)[0]


def index_headers(files):
    """{header name: [paths]} for the headers found by name (-I<layer> for every layer)."""
    names = {}
    for p in files:
        if os.path.dirname(p) in LAYERS:
            names.setdefault(os.path.basename(p), []).append(p)
    return names


def resolve(src, name, names):
    beside = os.path.normpath(os.path.join(os.path.dirname(src), name))
    if os.path.exists(os.path.join(ROOT, beside)):
        return beside
    for layer in LAYERS:
        p = os.path.normpath(os.path.join(layer, name))
        if os.path.exists(os.path.join(ROOT, p)):
            return p
    return None


def check():
    files = list(sources())
    names = index_headers(files)
    problems = []
    for name, paths in sorted(names.items()):
        if len(paths) > 1:
            problems.append(f"{', '.join(paths)}: one header name in two layers; rename one")
    edges = {}
    for src in files:
        ceiling = CEILING.get(src, layer_of(src))
        with open(os.path.join(ROOT, src), encoding="utf-8", errors="replace") as fh:
            for no, line in enumerate(fh, 1):
                m = INCLUDE.match(line)
                if not m:
                    continue
                hdr = resolve(src, m.group(1), names)
                if hdr is None:
                    problems.append(f'{src}:{no}: "{m.group(1)}" is in no layer folder')
                    continue
                a, b = layer_of(src), layer_of(hdr)
                edges[(a, b)] = edges.get((a, b), 0) + 1
                if LAYERS.index(b) > LAYERS.index(ceiling) and hdr not in CEILING:
                    problems.append(
                        f"{src}:{no}: includes {hdr} ({b}/), above {ceiling}/; move the shared "
                        f"part down a layer or the caller up (ARCHITECTURE.md)"
                    )
    return files, edges, problems


FUNC = re.compile(r"^[A-Za-z_][^;{}()]*\b(\w+)\s*\([^;]*$")


def function_lengths(path):
    """(name, lines) of each top-level function definition: a line opening a definition at
    column 0 and the next line that is a lone '}' closing it."""
    out, name, start = [], None, 0
    with open(os.path.join(ROOT, path), encoding="utf-8", errors="replace") as fh:
        for no, line in enumerate(fh, 1):
            if name is None:
                m = FUNC.match(line)
                if m and not line.startswith(("static const", "typedef", "#", "return")):
                    name, start = m.group(1), no
            elif line.startswith("}"):
                out.append((name, no - start + 1))
                name = None
            elif line.rstrip().endswith(";") and no == start + 1 and not line.startswith(" "):
                name = None
    return out


def table(files, edges):
    print("| layer | files | lines | functions | over 100 lines |")
    print("| --- | --- | --- | --- | --- |")
    for layer in LAYERS:
        own = [f for f in files if layer_of(f) == layer]
        lines = sum(sum(1 for _ in open(os.path.join(ROOT, f), errors="replace")) for f in own)
        funcs = [fl for f in own if f.endswith((".c", ".cpp")) for fl in function_lengths(f)]
        long = sorted((n for n in funcs if n[1] > 100), key=lambda x: -x[1])
        longs = ", ".join(f"{n} {k}" for n, k in long) or "none"
        print(f"| {layer}/ | {len(own)} | {lines} | {len(funcs)} | {longs} |")
    print()
    print("| includes from \\ to | " + " | ".join(LAYERS) + " |")
    print("| --- |" + " --- |" * len(LAYERS))
    for a in LAYERS:
        print(f"| {a} | " + " | ".join(str(edges.get((a, b), "")) for b in LAYERS) + " |")


def main():
    files, edges, problems = check()
    if "--table" in sys.argv[1:]:
        table(files, edges)
    for p in problems:
        print(f"layers: {p}", file=sys.stderr)
    if problems:
        print(f"layers: {len(problems)} include(s) point up or are ambiguous", file=sys.stderr)
        return 1
    print(f"layers: {len(files)} files in {len(LAYERS)} layers, every include points down or sideways")
    return 0


if __name__ == "__main__":
    sys.exit(main())
