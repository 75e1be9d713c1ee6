#!/usr/bin/python3
"""cost_scenes.py - N scene variants of the canonical scenes, for measuring how cost grows.

Usage: /usr/bin/python3 ops/cost_scenes.py N OUT [SCENE.yaml ...]   (ops/cost_growth.sh)

Writes OUT/<name>_vNNN.yaml for NNN = 0 .. N-1: the canonical scenes (default scenes/*.yaml,
sorted) taken in turn, each copy renamed and its camera's horizontal field of view widened by
0.1 % per round (1.001 on the first copy of a scene, 1.002 on the second, ...), so that every
variant is its own scene (its own cache key, a slightly different image) at the cost of the
scene it copies. OUT gets links to the scene folder's assets/ and envs/, which the scenes name
by relative path; a path that climbs out of the scene folder (../) is made absolute. OUT must not be the scenes/ folder (the variants are scratch, not versioned).
Prints the variants' paths, one per line.
"""

import glob
import os
import re
import sys


def variant(text, name, round_no, path):
    """The scene text renamed to `name`, its hfov widened by 0.1 % per round, and each `path:`
    that climbs out of the scene folder ("../", e.g. a user model's shared object in the build)
    made absolute, since the variant lives elsewhere."""
    here = os.path.dirname(os.path.abspath(path))
    text = re.sub(
        r'(\bpath:\s*)(\.\./[^\s,}]+)', lambda m: m.group(1) + os.path.normpath(os.path.join(here, m.group(2))), text
    )
    out, n_name = re.subn(r'^name:\s*\S+\s*$', f'name: {name}', text, count=1, flags=re.M)
    out, n_fov = re.subn(
        r'(hfov:\s*)([0-9.eE+-]+)',
        lambda m: f'{m.group(1)}{float(m.group(2)) * (1 + 0.001 * round_no):.6g}',
        out,
        count=1,
    )
    if n_name != 1 or n_fov != 1:
        raise ValueError(f'{path}: no top-level "name:" line or no camera "hfov:" to vary; give other scenes')
    return out


def main(argv):
    if len(argv) < 3 or not argv[1].isdigit():
        print(__doc__, file=sys.stderr)
        return 2
    count, out = int(argv[1]), argv[2]
    sources = argv[3:] or sorted(glob.glob('scenes/*.yaml'))
    if not sources:
        print('cost_scenes.py: no scene given and no scenes/*.yaml here; run from the project root', file=sys.stderr)
        return 2
    if os.path.realpath(out) == os.path.realpath(os.path.dirname(sources[0]) or '.'):
        print(f'cost_scenes.py: {out}: write the variants to a scratch folder, not beside the scenes', file=sys.stderr)
        return 2
    os.makedirs(out, exist_ok=True)
    src_dir = os.path.abspath(os.path.dirname(sources[0]) or '.')
    for sub in ('assets', 'envs'):
        link = os.path.join(out, sub)
        if os.path.isdir(os.path.join(src_dir, sub)) and not os.path.lexists(link):
            os.symlink(os.path.join(src_dir, sub), link)
    texts = []
    for path in sources:
        with open(path, encoding='utf-8') as f:
            texts.append((path, f.read()))
    for i in range(count):
        path, text = texts[i % len(texts)]
        base = os.path.splitext(os.path.basename(path))[0]
        name = f'{base}_v{i:03d}'
        try:
            body = variant(text, name, i // len(texts) + 1, path)
        except ValueError as e:
            print(f'cost_scenes.py: {e}', file=sys.stderr)
            return 1
        dest = os.path.join(out, name + '.yaml')
        with open(dest, 'w', encoding='utf-8') as f:
            f.write(body)
        print(dest)
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv))
