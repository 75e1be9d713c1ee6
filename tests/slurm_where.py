#!/usr/bin/python3
"""slurm_where.py - where each render job of a Slurm nightly ran, from Slurm's own record.

Usage: /usr/bin/python3 tests/slurm_where.py RUN JOBCOMP [--nodes N1,N2...] [--lost NODE TASK]
       (tests/slurm_nodes.sh)

JOBCOMP is the cluster's job completion log (jobcomp/filetxt, ops/slurm/local_cluster.sh):
one line per end of a job, a requeue included, with its JobState and NodeList. Prints one line
per render job RUN submitted (RUN/slurm/arrays): its Slurm array task, its record, the node the
record names, and every end Slurm logged for that task (STATE@NODES, in order). Checks,
printing each failure and exiting 1 on any:
  - every render record is ok and names its array task and a node, but a validate record the
    fits stage rewrote afterwards as a cache hit (it names no Slurm job; its node is Slurm's);
  - the last end Slurm logged for the task is COMPLETED on the node the record names;
  - --nodes: the jobs ran on every node listed (at least one job each);
  - --lost NODE TASK: array task TASK (ARRAY_TASK) ended once in NODE_FAIL on NODE and then
    COMPLETED on another node (requeued), and its record names that other node.
"""

import json
import os
import shlex
import sys

failures = []


def fail(text):
    failures.append(text)
    print('where: FAILED: ' + text)


def jobcomp_ends(path):
    """{ARRAY_TASK: [(state, nodelist), ...]} in the order Slurm logged them."""
    ends = {}
    with open(path, encoding='utf-8') as f:
        for line in f:
            fields = dict(w.split('=', 1) for w in line.split() if '=' in w)
            if 'ArrayJobId' not in fields:
                continue
            task = f"{fields['ArrayJobId']}_{fields['ArrayTaskId']}"
            ends.setdefault(task, []).append((fields.get('JobState'), fields.get('NodeList')))
    return ends


def plan_tasks(run):
    """[(ARRAY_TASK, record path)] of every render job the run submitted (RUN/slurm/arrays: each
    array's id and list file; line K of a list is task K: its record path, then its command)."""
    tasks = []
    with open(os.path.join(run, 'slurm', 'arrays'), encoding='utf-8') as f:
        for line in f.read().splitlines():
            array_id, listfile = line.split(' ', 1)
            with open(listfile, encoding='utf-8') as jobs:
                for k, job in enumerate(jobs.read().splitlines()):
                    tasks.append((f'{array_id}_{k}', shlex.split(job)[0]))
    return tasks


def main(argv):
    args = argv[1:]
    nodes, lost = [], None
    if '--nodes' in args:
        i = args.index('--nodes')
        nodes = args[i + 1].split(',')
        del args[i : i + 2]
    if '--lost' in args:
        i = args.index('--lost')
        lost = (args[i + 1], args[i + 2])
        del args[i : i + 3]
    if len(args) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    run, jobcomp = args
    ends = jobcomp_ends(jobcomp)
    used = set()
    seen_lost = False
    tasks = plan_tasks(run)
    for task, path in tasks:
        rel = os.path.relpath(path, run)
        try:
            with open(path, encoding='utf-8') as f:
                rec = json.load(f)
        except (OSError, ValueError) as e:
            fail(f'{rel}: no record ({e})')
            continue
        log = ends.get(task, [])
        slurm = rec.get('slurm') or {}
        node = slurm.get('node', '')
        # The fits stage runs a scene's validate job again, locally, through the cache (cli_fit.c),
        # and that rewrites the run's record as a cache hit naming no Slurm job.
        local = rec.get('slurm') is None and rec.get('cached')
        if local:
            node = log[-1][1] if log else ''
        print(
            f"where: {task:>8} {rel:<46} {rec['status']:<7} "
            f"{'record rewritten by the fits (cache hit)' if local else 'record node ' + (node or '-'):<41} "
            f"Slurm: {' '.join(f'{s}@{n}' for s, n in log) or 'no end logged'}"
        )
        used.add(node)
        if rec['status'] != 'ok' or not node or not (local or slurm.get('job_id') == task):
            fail(
                f'{rel}: status {rec["status"]}, Slurm task "{slurm.get("job_id")}" (the plan\'s: {task}), node "{node}"'
            )
        if not log or log[-1] != ('COMPLETED', node):
            fail(f'{rel}: Slurm logged {log} for task {task}, not COMPLETED last on {node}')
        if lost and task == lost[1]:
            seen_lost = True
            if len(log) != 2 or log[0] != ('NODE_FAIL', lost[0]) or node == lost[0]:
                fail(f'{rel}: task {task} should end NODE_FAIL on {lost[0]}, then COMPLETED elsewhere: {log}')
    for n in nodes:
        if n not in used:
            fail(f'no job ran on node {n} (nodes used: {sorted(used)})')
    if lost and not seen_lost:
        fail(f'no render record names the task {lost[1]} held on {lost[0]}')
    print(f'where: {len(tasks)} render jobs, nodes used {sorted(used)}; {len(failures)} failed')
    return 1 if failures else 0


if __name__ == '__main__':
    sys.exit(main(sys.argv))
