"""scenes.py - what the sweep needs to know of a scene file, asked of the C parser.

`reflcheck check --json SCENE` prints the scene as the harness parsed it (its name, image and
comparisons, each with its test resolved: `test_is_model`), so the sweep reads no YAML of its
own. The renderer table comes from `reflcheck renderers --json` the same way.
"""

import functools
import json
import os
import subprocess

from .common import ROOT


class SceneError(Exception):
    """A scene file the C parser refuses, or a reflcheck that cannot say: one line for stderr."""


# The reflcheck that answers (main sets it from --bin); REFLCHECK_BIN (the Makefile's test
# targets) or the build's own otherwise.
BIN = os.environ.get('REFLCHECK_BIN') or os.path.join(ROOT, 'build', 'reflcheck')


def use_bin(bin_path):
    global BIN
    BIN = bin_path
    scene_facts.cache_clear()


@functools.lru_cache(maxsize=None)
def scene_facts(path):
    """The scene as `reflcheck check --json` parsed it: {"scene", "image", "comparisons": [{"test",
    "test_is_model", "reference", "role", ...}]}. Raises SceneError naming the file."""
    try:
        p = subprocess.run([BIN, 'check', '--json', path], capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.SubprocessError) as e:
        raise SceneError(f'{path}: {BIN} check --json: {e}; build it with `make build/reflcheck`') from e
    if p.returncode != 0:
        lines = p.stderr.strip().splitlines()
        raise SceneError(lines[-1] if lines else f'{path}: reflcheck check --json exited {p.returncode}')
    try:
        return json.loads(p.stdout)
    except ValueError as e:
        raise SceneError(f'{path}: reflcheck check --json printed no JSON ({e}); rebuild reflcheck') from e


def scene_name(path):
    return scene_facts(path)['scene']


def renderer_table(bin_path):
    """The renderer table as the CLI lists it: name -> row (model, stochastic, program, ...).
    The sweep keeps no renderer list of its own."""
    out = subprocess.run(
        [bin_path, 'renderers', '--json'], capture_output=True, text=True, check=True, timeout=30
    ).stdout
    return {r['name']: r for r in json.loads(out)}


def lists_cycles(path, role):
    """True if the scene's comparisons hold {reference: cycles, role: ROLE} with the model
    renderer as the test (the default, or `test:` naming it)."""
    return any(
        c['reference'] == 'cycles' and c['role'] == role and c['test_is_model']
        for c in scene_facts(path)['comparisons']
    )


def names_renderer(path, name):
    """True if one of the scene's comparisons names the renderer (as test or reference)."""
    return any(name in (c['test'], c['reference']) for c in scene_facts(path)['comparisons'])


def lists_cycles_validate(path):
    return lists_cycles(path, 'validate')


def sweep_role(path):
    """The best reference a scene offers: Cycles validate (the physics), else Cycles twin (the
    converged render of our own model: then the errors are sampling and harness error), else
    None (the scene is left out)."""
    for role in ('validate', 'twin'):
        if lists_cycles(path, role):
            return role
    return None
