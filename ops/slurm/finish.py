#!/usr/bin/python3
"""finish.py - records for the render jobs Slurm ended before they wrote their own.

Usage (from the project root, after every render task of RUN, e.g. in a job submitted with
--dependency=afterany:IDS):
    /usr/bin/python3 ops/slurm/finish.py RUN

RUN/slurm/arrays (written by the submit script of `reflcheck plan --scheduler slurm`) lists
each array job id and its list file; line K of a list is array task K: the job's record path,
then its `reflcheck run` command, as shell words. A job whose record is missing or names
another Slurm job (an older run's) ended without writing it: cancelled (scancel, pending or
running), killed at its time limit, lost with its node, out of memory. Its record is then
written by that same command with --record-status, exactly as a local run records such a
job: the status (timeout for TIMEOUT and DEADLINE, failed for FAILED, crashed for the
others, error when Slurm no longer knows the job or says it completed), a message naming the
Slurm job and state, and the task's Slurm output file as the log. A task Slurm no longer knows
and that left no output file never ran: cancelled while pending (crashed).

Slurm's state comes from sacct where accounting is set up, else from scontrol (which keeps
finished jobs for MinJobAge; the local cluster keeps them an hour).

Exit status: 0 every job has a record and is ok or skipped; 1 a job failed (in any way, its
record says how) or a record could not be written; 2 bad usage.
"""

import json
import os
import shlex
import subprocess
import sys

# What a Slurm state means for the job's record: (status, why).
STATES = {
    'TIMEOUT': ('timeout', 'Slurm stopped it at its time limit'),
    'DEADLINE': ('timeout', 'Slurm stopped it at its deadline'),
    'CANCELLED': ('crashed', 'Slurm cancelled it (scancel or an administrator)'),
    'NODE_FAIL': ('crashed', 'its node failed'),
    'BOOT_FAIL': ('crashed', 'its node failed to boot'),
    'OUT_OF_MEMORY': ('crashed', 'it ran out of memory'),
    'PREEMPTED': ('crashed', 'Slurm preempted it'),
    'REVOKED': ('crashed', 'Slurm revoked it'),
    'FAILED': ('failed', 'it exited with a failure'),
    'COMPLETED': ('error', 'it completed without writing its record'),
}


def slurm_state(job_id):
    """(state, exit code text) of a Slurm job, or (None, why)."""
    try:
        r = subprocess.run(
            ['sacct', '-n', '-X', '-P', '-o', 'State,ExitCode', '-j', job_id],
            capture_output=True,
            text=True,
            timeout=60,
        )
        line = r.stdout.strip().splitlines()[0] if r.returncode == 0 and r.stdout.strip() else ''
        if line:
            state, code = (line.split('|') + [''])[:2]
            return state.split()[0], code
    except (OSError, subprocess.SubprocessError):
        pass
    try:
        r = subprocess.run(['scontrol', '-o', 'show', 'job', job_id], capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.SubprocessError) as e:
        return None, str(e)
    if r.returncode != 0:
        return None, (r.stderr.strip() or 'unknown job').splitlines()[-1]
    fields = dict(w.split('=', 1) for w in r.stdout.split() if '=' in w)
    return fields.get('JobState'), fields.get('ExitCode', '')


def read_record(path):
    try:
        with open(path, encoding='utf-8') as f:
            return json.load(f)
    except (OSError, ValueError):
        return None


def record_job_id(path):
    """The Slurm id in a job record, '' without one, None without a readable record."""
    rec = read_record(path)
    return None if rec is None else (rec.get('slurm') or {}).get('job_id', '')


def verdict(job_id, state, code, started):
    """The record status and message for a job Slurm ended in `state` (None: Slurm no longer
    knows it; started: it left a Slurm output file)."""
    if state is None and not started:
        # Without accounting Slurm forgets an array task cancelled while pending at once.
        return 'crashed', (
            f'slurm job {job_id}: never ran: Slurm no longer knows it ({code}) and it left no output; '
            'cancelled while pending (sacct has it where accounting runs)'
        )
    if state is None:
        return 'error', f'slurm job {job_id}: no record, and Slurm no longer knows the job ({code})'
    base = state.rstrip('+')
    status, why = STATES.get(base, ('error', f'it ended in state {base} without its record'))
    if base == 'FAILED' and code:
        why += f' (exit code {code})'
    return status, f'slurm job {job_id}: {base}: {why}'


def finish(run):
    arrays = os.path.join(run, 'slurm', 'arrays')
    try:
        with open(arrays, encoding='utf-8') as f:
            entries = [line.split(' ', 1) for line in f.read().splitlines() if line.strip()]
    except OSError as e:
        print(f'finish.py: {arrays}: {e}; submit the plan with its submit script first', file=sys.stderr)
        return 2
    rc = 0
    repaired = 0
    failed = 0
    for array_id, listfile in entries:
        with open(listfile, encoding='utf-8') as f:
            lines = f.read().splitlines()
        for task, line in enumerate(lines):
            words = shlex.split(line)
            record, cmd = words[0], words[1:]
            job_id = f'{array_id}_{task}'
            if record_job_id(record) == job_id:
                failed += (read_record(record) or {}).get('status') not in ('ok', 'skipped')
                continue
            log = os.path.join(run, 'slurm', f'{job_id}.out')
            state, code = slurm_state(job_id)
            status, message = verdict(job_id, state, code, os.path.isfile(log))
            extra = ['--record-status', status, '--record-message', message, '--slurm-job', job_id]
            if os.path.isfile(log):
                extra += ['--record-log', log]
            # Options go before the `--` that ends them (the scene path follows it).
            cut = cmd.index('--') if '--' in cmd else len(cmd)
            r = subprocess.run(cmd[:cut] + extra + cmd[cut:], capture_output=True, text=True)
            if record_job_id(record) != job_id:
                print(f'finish.py: {record}: could not write the record: {r.stderr.strip()}', file=sys.stderr)
                rc = 1
                continue
            repaired += 1
            failed += 1
            print(f'finish: {record}: {status}: {message}')
    print(f'finish: {repaired} job(s) recorded for Slurm; {failed} job(s) neither ok nor skipped')
    return 1 if rc or failed else 0


def main(argv):
    if len(argv) != 2:
        print('usage: finish.py RUN', file=sys.stderr)
        return 2
    return finish(argv[1])


if __name__ == '__main__':
    sys.exit(main(sys.argv))
