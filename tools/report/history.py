"""history - the append-only history file: one JSON line per run (reports/README.md); a run that
ended before it could be reported has status failed and a reason."""

import json
import os

from .load import all_comparisons, flat_metrics, run_status, verdict_counts
from .util import clean


def history_record(R):
    metrics = {}
    for s, c in all_comparisons(R):
        m = {'role': c['role'], 'status': c['status']}
        m.update(flat_metrics(c))
        for t in c['thresholds']:
            m[f'verdict.{t["metric"]}'] = t.get('verdict')
        metrics.setdefault(s['name'], {})[c['id']] = m
    return clean(
        {
            'run_id': R['run_id'],
            'commit': R['commit'],
            'time': R['time'],
            'report_time': R['report_time'],
            'versions': R['versions'],
            'machine': R['machine'],
            'status': run_status(R),
            'counts': verdict_counts(R),
            'metrics': metrics,
        }
    )


def failed_record(run_id, commit, reason):
    """The history line of a run that ended before it could be reported (a scheduler refused
    its jobs): no figures, status failed, and why."""
    import time

    return {
        'run_id': run_id,
        'commit': commit or 'unknown',
        'time': time.strftime('%Y-%m-%dT%H:%M:%SZ', time.gmtime()),
        'status': 'failed',
        'reason': reason,
    }


def trend_history(reference, local):
    """The project's reference runs (marked 'reference': true), then this machine's own runs
    that the reference does not hold already, each list in its file order."""
    ref_ids = {r['run_id'] for r in reference}
    return [dict(r, reference=True) for r in reference] + [r for r in local if r['run_id'] not in ref_ids]


def read_history(path, problems=None):
    """Records in file order; a line that does not parse (a run killed mid-write) is skipped and
    reported. Several lines of one run id: the last one wins, at the place of the first."""
    out, order = {}, []
    try:
        with open(path, 'rb') as f:
            data = f.read()
    except FileNotFoundError:
        return []
    for no, line in enumerate(data.split(b'\n'), 1):
        if not line.strip():
            continue
        try:
            rec = json.loads(line.decode('utf-8'))
            if not isinstance(rec, dict) or 'run_id' not in rec:
                raise ValueError('not a run record')
        except (ValueError, UnicodeDecodeError) as e:
            if problems is not None:
                problems.add(
                    f'{path}:{no}',
                    f'history line skipped (truncated or corrupt: {str(e)[:80]}); ' 'earlier runs are unaffected',
                )
            continue
        if rec['run_id'] not in out:
            order.append(rec['run_id'])
        out[rec['run_id']] = rec
    return [out[k] for k in order]


def append_history(path, rec, problems):
    """One os.write of the whole line, then fsync: a kill leaves at worst a partial last line,
    which readers skip. O_APPEND never truncates. A partial line left by an earlier crash is
    closed with a newline first (in the same write) so that this record stays parseable."""
    existing = read_history(path)
    same = [r for r in existing if r.get('run_id') == rec['run_id']]
    if same and {k: v for k, v in same[-1].items() if k != 'report_time'} == {
        k: v for k, v in rec.items() if k != 'report_time'
    }:
        return False
    line = json.dumps(rec, separators=(',', ':'), sort_keys=True).encode('utf-8') + b'\n'
    os.makedirs(os.path.dirname(os.path.abspath(path)) or '.', exist_ok=True)
    created = not os.path.exists(path)
    fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
    try:
        size = os.fstat(fd).st_size
        if size > 0:
            with open(path, 'rb') as f:
                f.seek(size - 1)
                if f.read(1) != b'\n':
                    line = b'\n' + line
        n = os.write(fd, line)
        while n < len(line):
            n += os.write(fd, line[n:])
        os.fsync(fd)
    finally:
        os.close(fd)
    if created:
        dfd = os.open(os.path.dirname(os.path.abspath(path)), os.O_RDONLY)
        try:
            os.fsync(dfd)
        finally:
            os.close(dfd)
    return True
