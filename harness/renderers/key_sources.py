"""key_sources.py - the source files each renderer's cache key covers, from the build itself.

Usage (the Makefile runs it after compiling, harness/jobs.c reads what it writes):
    python3 harness/renderers/key_sources.py BUILD OBJECT...   (the library's objects)
writes BUILD/key-sources/NAME.list for every renderer folder harness/renderers/NAME/: one path a
line, relative to the source tree, sorted.

A renderer's render depends on the code its translator calls and on the scene pipeline. Both are
found from the objects, never from a hand-written list: starting at the renderer's own objects
(BUILD/harness/renderers/NAME/*.o) and the pipeline's (jobs.o, renderer.o), every object of
the build that defines a symbol an object already taken uses (`nm`) is taken too, and the list
is every tree file the compiler recorded for those objects (their -MMD .d files: sources and
the headers they include), the scripts (*.py) in the folders of the renderers taken, and the
DDS plugin's sources (loaded at run time, so no symbol leads to it). The renderer table
(registry.o) and the command line (cli*.o, main.o) are not followed: through the table every
renderer would reach every other.
"""

import glob
import os
import subprocess
import sys

# Objects whose references are not followed (see above).
STOP = ("harness/renderers/registry.o", "cli/main.o")
STOP_PREFIX = ("cli/cli",)
# The DDS plugin, dlopen'ed by scene/image_dds.c.
PLUGIN = ("pic/scene/image_oiio.o",)


def nm(build, objs, *flags):
    """{object: [symbol, ...]} from one nm call over all objects."""
    paths = [os.path.join(build, o) for o in objs]
    out = subprocess.run(["nm", "-A", *flags, *paths], check=True, capture_output=True, text=True).stdout
    syms = {o: [] for o in objs}
    for line in out.splitlines():
        path, _, rest = line.partition(":")
        if rest.strip():
            syms[os.path.relpath(path, build)].append(rest.split()[-1])
    return syms


def deps(dfile):
    """The prerequisites of the first rule of a .d file that lie in the tree."""
    with open(dfile) as fh:
        text = fh.read().replace("\\\n", " ")
    first = text.split("\n", 1)[0]
    _, _, prereqs = first.partition(":")
    return [os.path.normpath(p) for p in prereqs.split() if not os.path.isabs(p)]


def main():
    if len(sys.argv) < 3:
        sys.exit("usage: key_sources.py BUILD OBJECT...")
    build = sys.argv[1]
    # The library's objects as the Makefile names them: a folder walk would also take objects a
    # moved or deleted source left behind in an old build folder.
    objs = sorted(os.path.relpath(o, build) for o in sys.argv[2:])
    defined = {}
    for o, syms in nm(build, objs, "--defined-only", "-g").items():
        for sym in syms:
            defined.setdefault(sym, o)
    undefined = nm(build, objs, "--undefined-only")
    out_dir = os.path.join(build, "key-sources")
    os.makedirs(out_dir, exist_ok=True)
    for folder in sorted(glob.glob(os.path.join("harness", "renderers", "*", ""))):
        name = os.path.basename(os.path.dirname(folder))
        own = [o for o in objs if o.startswith(folder)]
        todo = own + ["harness/jobs.o", "harness/renderers/renderer.o"]
        taken = set()
        while todo:
            o = todo.pop()
            if o in taken or o not in objs:
                continue
            taken.add(o)
            if o in STOP or o.startswith(STOP_PREFIX):
                continue
            for sym in undefined[o]:
                if sym in defined:
                    todo.append(defined[sym])
        taken = {o for o in taken if o not in STOP and not o.startswith(STOP_PREFIX)}
        files = set()
        for o in sorted(taken) + list(PLUGIN):
            dfile = os.path.join(build, o[:-2] + ".d")
            if os.path.exists(dfile):
                files.update(deps(dfile))
            if os.path.dirname(os.path.dirname(o)) == "harness/renderers":
                files.update(glob.glob(os.path.join(os.path.dirname(o), "*.py")))
        tmp = os.path.join(out_dir, name + ".list.tmp")
        with open(tmp, "w") as fh:
            fh.write("".join(f + "\n" for f in sorted(files)))
        os.replace(tmp, os.path.join(out_dir, name + ".list"))


if __name__ == "__main__":
    main()
