#!/usr/bin/env bash
# benchmarks/bench_dask_batch.sh: 32 copies of the bundled session + 1 broken session: a local batch (2 workers) and the same through a
# hand-started Dask cluster (scheduler + 2 workers on this machine); compare the tables.
# Needs dask[distributed] (pip install -e ".[cluster]"); DASK_VENV_BIN names the bin folder of a Python
# that has it and horsemocap (default: the folder of the python on PATH).
set -u
R=/tmp/b32; rm -rf $R; mkdir -p $R/sessions
SRC=$(python -c "from horsemocap.data import default_session_dir; print(default_session_dir())")
for k in $(seq -w 1 32); do cp -r "$SRC" $R/sessions/canter$k; done
cp -r "$SRC" $R/sessions/broken; echo '{"format": ' > $R/sessions/broken/session.json
uptime
/usr/bin/time -f "local batch: %e s wall" horsemocap batch $R/sessions --out $R/local --workers 2 2>$R/local.err >$R/local.out; echo "local exit $?"; tail -1 $R/local.err
V=${DASK_VENV_BIN:-$(dirname "$(command -v python)")}
cd $R && ($V/dask scheduler --port 8786 --no-dashboard > $R/sched.log 2>&1 &) ; sleep 4
($V/dask worker tcp://127.0.0.1:8786 --nworkers 1 --nthreads 1 --no-dashboard > $R/w1.log 2>&1 &)
($V/dask worker tcp://127.0.0.1:8786 --nworkers 1 --nthreads 1 --no-dashboard > $R/w2.log 2>&1 &)
sleep 6
/usr/bin/time -f "dask batch: %e s wall" $V/python -m horsemocap.cli batch $R/sessions --out $R/dask --scheduler tcp://127.0.0.1:8786 2>$R/dask.err >$R/dask.out; echo "dask exit $?"; tail -1 $R/dask.err
pkill -f "dask scheduler --port 8786"; pkill -f "dask worker tcp://127.0.0.1:8786"
python - <<'PY'
import csv
def rows(p):
    r = list(csv.DictReader(open(p)))
    return {x['session'] if 'session' in x else x[list(x)[0]]: x for x in r}, list(r[0])
a, cols = rows('/tmp/b32/local/sessions.csv'); b, _ = rows('/tmp/b32/dask/sessions.csv')
skip = {c for c in cols if any(w in c for w in ('second', 'time_s', 'started', 'finished', 'results', 'path', 'host', 'worker'))}
diff = [(k, c, a[k][c], b[k][c]) for k in a for c in cols if c not in skip and a[k].get(c) != b.get(k, {}).get(c)]
print('rows', len(a), len(b), 'columns compared', len(cols) - len(skip), 'skipped', sorted(skip))
print('differences:', len(diff), diff[:5])
print('broken row:', {c: a.get('broken', {}).get(c) for c in cols if c in ('exit_status', 'status', 'verdict', 'error')})
PY
