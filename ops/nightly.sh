#!/usr/bin/env bash
# The nightly run (`make report`): every canonical scene in every renderer its comparisons
# list, full size; then metrics, the stability table and the report. A run writes only into
# its own folder reports/runs/<id>; reports/latest moves to it at the very end and the
# history gets one appended line, so a run killed midway leaves both as they were.
#
# Usage: ops/nightly.sh [OPTION...] [SCENE.yaml ...]     (ops/nightly.sh --help lists them)
#   bash ops/nightly.sh --small --no-sweep --scenes my/a.yaml my/b.yaml   a user's own scenes
# Every option has an environment variable as its fallback (an option wins over its variable):
# --scenes SCENES, --small SMALL, --no-sweep NO_SWEEP, --no-screenshot NO_SCREENSHOT, --jobs JOBS,
# --runs RUNS, --cache CACHE, --run-id RUN_ID, --scheduler SCHEDULER, --reference REFERENCE,
# --bin BIN, --history HISTORY, --latest LATEST. Scenes: the arguments, else $SCENES, else
# scenes/*.yaml. Scene paths given as arguments (or after --scenes) may hold spaces and any other
# character. SCENES holds one path per line when it holds a line break, else space-separated
# paths; a word that is not a file is refused (exit 2).
#
# Progress: every stage (renders, sweep, fits, stability, report) shows done/total and the time
# left at least every 10 s on stderr, one updating line on a terminal, plain lines in a log
# (tools/progress.py); a failed job is named when it fails ("renders: FAILED scene/job: why").
#
# History: a run appends its line to reports/local/history.jsonl (ignored by git: a user's own
# runs never change a versioned file); the report's trend plots show the project's reference
# history (reports/history.jsonl, read only) and then the local runs, told apart. REFERENCE=1
# names this run the project's reference run on purpose: its line goes to reports/history.jsonl.
# A Slurm run that fails to submit records a line with status "failed" and the reason.
#
# Cache: CACHE keeps what a second run with nothing changed takes back instead of doing it
# again: the renders (the job cache), the sweep's renders, the measurements (CACHE/compare), the
# fits, the stability table and the report's plots (CACHE/report), a cube map's converted image
# for the renders and the sweep (CACHE/env); Blender workers start only
# for a job the cache cannot answer.
#
# Exit status: 0 when every job ran (or was skipped: renderer not installed, or it cannot
# represent the scene) and no comparison failed; 1 when a job or step failed or a comparison
# failed or errored (the run is still reported and recorded, with its status); 2 bad input.
# Killed or interrupted (SIGINT, SIGTERM, SIGHUP), it stops every process it started,
# renderers included, before it exits.
#
# Settings (environment, the options' fallback): BIN, JOBS, RUNS, HISTORY (the file this run
# appends to), REFERENCE_HISTORY (read for the trends only; empty: none), REFERENCE=1, LATEST,
# CACHE, SCENES, RUN_ID, SMALL=1 (test-size renders), NO_SWEEP=1, NO_SCREENSHOT=1 (any non-empty
# value), SCHEDULER.
#
# SCHEDULER=slurm (default make): the render jobs, the sweep and the compare step run as Slurm
# jobs (docs/slurm.md): `plan --scheduler slurm` submits one array task per render; the sweep
# is one job of JOBS CPUs on one node (SWEEP_MINUTES, default 240) whose renders are srun steps;
# compare runs after all of them (afterany), first writing the records of jobs Slurm ended;
# stability, the plot and the report run here. RUN and CACHE must be on a filesystem every node
# shares, at the same path. Interrupted, the nightly cancels its Slurm jobs (scancel).
set -uo pipefail
cd "$(dirname "$0")/.."
say() { echo "reflcheck nightly: $*" >&2; }
usage() {
    cat <<'TXT'
usage: bash ops/nightly.sh [OPTION...] [SCENE.yaml ...]
The nightly run: render the scenes in every renderer their comparisons list, compare, fit,
stability table, report. A run writes only into RUNS/<run id>; options win over the environment
variable named on the right, which is the fallback.
  --scenes PATH...       scene files (the words up to the next --option); also the   SCENES
                         arguments; default: scenes/*.yaml
  --small                test-size renders (seconds, not minutes)                    SMALL=1
  --no-sweep             skip the error-against-time sweep                           NO_SWEEP=1
  --no-screenshot        no screenshot of the report                                 NO_SCREENSHOT=1
  --jobs N               render jobs at a time (default 2)                           JOBS
  --runs DIR             where run folders go (default reports/runs, not versioned)  RUNS
  --cache DIR            render cache (default reports/cache, not versioned)         CACHE
  --run-id ID            the run folder's name (default: time-commit-pid-random)     RUN_ID
  --scheduler NAME       make (default) or slurm (docs/slurm.md)                     SCHEDULER
  --reference            the project's reference run: append to the versioned        REFERENCE=1
                         reports/history.jsonl (default: reports/local/history.jsonl)
  --bin PATH             the reflcheck program (default build/reflcheck)             BIN
  --history FILE         the history this run appends to                             HISTORY
  --latest PATH          the link that moves to the run (default reports/latest)     LATEST
  --help                 this text
Environment only: REFERENCE_HISTORY (the history the trends show first; default
reports/history.jsonl), SWEEP_MINUTES (the Slurm sweep's time limit; default 240),
REFLCHECK_PROGRESS=tty|log (progress lines: one updating line, or plain lines; default: tty when
stderr is a terminal).
Your own scenes, nothing versioned changed:
  bash ops/nightly.sh --small --no-sweep --runs /tmp/myruns my/a.yaml my/b.yaml
Exit status: 0 all ran and no comparison failed; 1 a job, step or comparison failed; 2 bad input.
TXT
}
# The options, each kept in opt_<name> (unset: the environment variable, then the default).
unset opt_small opt_no_sweep opt_no_screenshot opt_reference opt_jobs opt_runs opt_cache opt_run_id \
    opt_scheduler opt_bin opt_history opt_latest
scenes=()
from_args=0
while [ $# -gt 0 ]; do
    arg=$1
    eq=0
    if [[ $arg == --*=* ]]; then  # --jobs=2 is --jobs 2
        eq=1
        set -- "${arg%%=*}" "${arg#*=}" "${@:2}"
        arg=$1
    fi
    case $arg in --help | -h) usage; exit 0 ;; esac
    case $eq$arg in
        1--small | 1--no-sweep | 1--no-screenshot | 1--reference | 1--scenes)
            say "option $arg takes no '=VALUE'; see bash ops/nightly.sh --help"
            exit 2 ;;
    esac
    case $arg in
        --small) opt_small=1 ;;
        --no-sweep) opt_no_sweep=1 ;;
        --no-screenshot) opt_no_screenshot=1 ;;
        --reference) opt_reference=1 ;;
        --scenes)
            from_args=1
            while [ $# -gt 1 ] && [[ $2 != --* ]]; do scenes+=("$2"); shift; done ;;
        --jobs | --runs | --cache | --run-id | --scheduler | --bin | --history | --latest)
            if [ $# -lt 2 ] || { [ $eq = 0 ] && [[ $2 == --* ]]; }; then
                say "$arg needs a value (see bash ops/nightly.sh --help)"
                exit 2
            fi
            name=${arg#--}
            printf -v "opt_${name//-/_}" '%s' "$2"
            shift ;;
        --) shift; from_args=1; scenes+=("$@"); break ;;
        --*) say "option '$arg' is not known; see bash ops/nightly.sh --help"; exit 2 ;;
        *) from_args=1; scenes+=("$arg") ;;
    esac
    shift
done
# setting OPTION VAR: which of the two gave the value (for messages), the option first.
setting() { if [ -n "${!2+x}" ]; then echo "$1"; else echo "$3"; fi; }
bin=${opt_bin:-${BIN:-build/reflcheck}}
bin_name=$(setting --bin opt_bin BIN)
jobs=${opt_jobs-${JOBS:-2}}
jobs_name=$(setting --jobs opt_jobs JOBS)
runs=${opt_runs:-${RUNS:-reports/runs}} # where run folders go
runs_name=$(setting --runs opt_runs RUNS)
[ -n "${opt_reference:-}" ] && REFERENCE=1
# The versioned history is the project's reference; a run writes there only when named so.
if [ -n "${REFERENCE:-}" ]; then
    history=${opt_history:-${HISTORY:-reports/history.jsonl}}
    reference_history=${REFERENCE_HISTORY-}
else
    history=${opt_history:-${HISTORY:-reports/local/history.jsonl}}
    reference_history=${REFERENCE_HISTORY-reports/history.jsonl}
fi
history_name=$(setting --history opt_history HISTORY)
case $jobs in
    *[!0-9]* | "" | 0*)
        say "$jobs_name '$jobs': give a whole number of parallel jobs, 1 or more (e.g. $([ "$jobs_name" = JOBS ] && echo JOBS=2 || echo --jobs 2))"
        exit 2 ;;
esac
if ! { [ -f "$bin" ] && [ -x "$bin" ]; } && { [[ $bin == */* ]] || ! command -v "$bin" > /dev/null; }; then
    say "$bin_name '$bin' is not an executable file; build it (make all) or point $bin_name at build*/reflcheck"
    exit 2
fi
latest=${opt_latest:-${LATEST:-reports/latest}}
cache=${opt_cache:-${CACHE:-reports/cache}}
# A cube map's equirectangular conversion (harness/jobs.h job_env_cube_file) is kept once for the
# renders and the sweep, whose job caches differ (CACHE and CACHE/sweep).
export REFLCHECK_ENV_CACHE=${REFLCHECK_ENV_CACHE:-$cache/env}
[ -n "${opt_small:-}" ] && SMALL=1
[ -n "${opt_no_sweep:-}" ] && NO_SWEEP=1
small=${SMALL:+--small} # SMALL=1: the test-size renders (used by the kill test)
screenshot=--screenshot
[ -n "${opt_no_screenshot:-${NO_SCREENSHOT:-}}" ] && screenshot=
scheduler=${opt_scheduler:-${SCHEDULER:-make}}
scheduler_name=$(setting --scheduler opt_scheduler SCHEDULER)
case $scheduler in
    make | slurm) ;;
    *)
        say "$scheduler_name '$scheduler': use make (the default) or slurm"
        exit 2 ;;
esac
if [ "$scheduler" = slurm ] && ! sinfo -h > /dev/null 2>&1; then
    echo "reflcheck nightly: SCHEDULER=slurm, but no Slurm cluster answers (sinfo failed); set SLURM_CONF," \
        "or start a local one: eval \"\$(ops/slurm/local_cluster.sh start)\"" >&2
    exit 2
fi
commit=$(git rev-parse --short HEAD 2>/dev/null || echo nogit)
# Two runs started in the same second (two users, a cluster) must not share a folder: the
# pid and a random number follow the time and commit (report.py reads those two).
id=${opt_run_id:-${RUN_ID:-$(date -u +%Y%m%d-%H%M%S)-$commit-$$-$(printf '%04x' "$RANDOM")}}
case $id in
    "" | *[!A-Za-z0-9_.-]*)
        say "$(setting --run-id opt_run_id RUN_ID) '$id': use letters, digits, _ . and -"
        exit 2 ;;
esac
run=$runs/$id
# The scene paths as one array, so that a path with a space reaches every command whole.
if [ $from_args = 0 ] && [ -n "${SCENES:-}" ]; then
    if [[ $SCENES == *$'\n'* ]]; then
        mapfile -t scenes <<< "$SCENES"
    else
        read -r -a scenes <<< "$SCENES"
    fi
elif [ $from_args = 0 ]; then
    scenes=(scenes/*.yaml)
fi
for i in "${!scenes[@]}"; do
    [ -z "${scenes[$i]}" ] && unset "scenes[$i]" # an empty line of a SCENES list
done
scenes=("${scenes[@]}")
[ ${#scenes[@]} -eq 0 ] && { say "no scene given; pass scene paths as arguments, after --scenes or in SCENES"; exit 2; }
for s in "${scenes[@]}"; do
    if [ ! -f "$s" ]; then
        say "scene '$s' is not a file; check the path, and give a path holding spaces as an argument" \
            "(ops/nightly.sh 'my scenes/a.yaml') or one path per line in SCENES"
        exit 2
    fi
done
if [ -d "$history" ]; then
    say "$history_name '$history' is a folder; point $history_name at a file (default reports/local/history.jsonl)"
    exit 2
fi
if [ -e "$runs" ] && [ ! -d "$runs" ]; then
    say "$runs_name '$runs' is not a folder; point $runs_name at a folder (default reports/runs)"
    exit 2
fi
mkdir -p "$runs" || { say "$runs_name '$runs': cannot create the folder; point $runs_name at a writable folder"; exit 2; }
if ! mkdir "$run" 2>/dev/null; then
    if [ -e "$run" ]; then
        say "$run exists already; give another run id (--run-id or RUN_ID), or leave it unset"
    else
        say "$run: cannot create the run folder in $runs_name '$runs'; make it writable or set $runs_name"
    fi
    exit 2
fi
echo "reflcheck nightly: run $id -> $run"

# Children run in the background and are waited for, so that a signal reaches the trap at
# once; the trap stops every descendant (make forwards SIGTERM to its jobs, and a renderer
# also dies with the `reflcheck run` that started it), then exits.
descendants() {
    local c
    for c in $(pgrep -P "$1" 2>/dev/null); do
        echo "$c"
        descendants "$c"
    done
}
# The Slurm jobs this run submitted: render arrays (RUN/slurm/arrays), sweep and compare.
slurm_jobs() {
    [ -r "$run/slurm/arrays" ] && cut -d' ' -f1 "$run/slurm/arrays"
    [ -r "$run/slurm/steps" ] && cat "$run/slurm/steps"
}
stop_all() {
    trap '' INT TERM HUP
    local pids ids
    if [ "$scheduler" = slurm ]; then
        ids=$(slurm_jobs 2>/dev/null)
        # shellcheck disable=SC2086
        [ -n "$ids" ] && scancel $ids 2>/dev/null
    fi
    pids=$(descendants $$)
    # shellcheck disable=SC2086
    [ -n "$pids" ] && kill -TERM $pids 2>/dev/null
    sleep 2
    pids=$(descendants $$)
    # shellcheck disable=SC2086
    [ -n "$pids" ] && kill -KILL $pids 2>/dev/null
    echo "reflcheck nightly: interrupted; run $id left incomplete in $run (history and latest unchanged)" >&9
    exit 130
}
# The trap runs inside whatever step was waiting, with that step's redirections: fd 9 keeps the
# nightly's own stderr, so the message above reaches the user and not a step's log file.
exec 9>&2
trap stop_all INT TERM HUP
step() {
    "$@" &
    wait $!
}

# A run that ended before its report (Slurm refused a submission): one history line with status
# failed and the reason, so that the history lists every run that was started.
record_failed() {
    echo "reflcheck nightly: $1" >&2
    /usr/bin/python3 tools/report.py --run "$run" --history "$history" --commit "$commit" --failed "$1" ||
        echo "reflcheck nightly: could not record the failed run in $history" >&2
}

# Waits until Slurm job $1 has left the queue (finished in any way).
# squeue failing for 10 minutes in a row (the controller gone) ends the wait with status 1: the
# jobs may still finish, and the run's folder holds whatever they wrote.
slurm_wait() {
    local state failures=0
    while :; do
        if state=$(squeue -h -j "$1" -o %T 2>/dev/null); then
            failures=0
            [ -z "$state" ] && return 0
        else
            failures=$((failures + 1))
            [ $failures -ge 300 ] && return 1
        fi
        step sleep 2
    done
}

# Progress (tools/progress.py) on the nightly's stderr: a terminal's mode, one updating line,
# holds for the stages whose stderr goes through a pipe (tee) too.
if [ -z "${REFLCHECK_PROGRESS:-}" ]; then
    REFLCHECK_PROGRESS=log
    [ -t 2 ] && REFLCHECK_PROGRESS='tty'
    export REFLCHECK_PROGRESS
fi
progress() { step /usr/bin/python3 tools/progress.py "$@"; }
# Each stage's wall time goes to RUN/stages.tsv; the last run's ($latest) is the next run's
# estimate of a stage of one unit (stability, the report) before it ends. The third column is
# the stage's CPU seconds (user + system of the processes it waited for, Blender workers
# included): on a shared machine wall time measures the others' load too, CPU time does not.
# `times` runs in this shell (a $(...) subshell has no children of its own); its second line is
# the children's "XmY.YYYs XmY.YYYs".
# cpu_of FILE [LINES]: the seconds of `times` output lines LINES (an awk condition; default the
# children's line).
cpu_of() {
    awk "${2:-NR == 2}"' { for (i = 1; i <= 2; i++) { split($i, t, "m"); s += t[1] * 60 + t[2] } } END { printf "%.1f", s }' "$1"
}
cpu_mark=0
# stage_done NAME START [CPU]: NAME's line; CPU: seconds of a stage that ran beside it, already
# written on its own line, left out of NAME's.
stage_done() {
    local now
    times > "$run/.times"
    now=$(cpu_of "$run/.times")
    rm -f "$run/.times"
    printf '%s\t%s\t%s\n' "$1" "$(($(date +%s) - $2))" "$(awk -v a="$now" -v b="$cpu_mark" -v c="${3:-0}" 'BEGIN { printf "%.1f", a - b - c }')" >> "$run/stages.tsv"
    cpu_mark=$now
}
expected() {
    local s
    s=$(awk -F'\t' -v k="$1" '$1 == k { v = $2 } END { if (v != "") print v }' "$latest/stages.tsv" 2> /dev/null)
    [ -n "$s" ] && [ "$s" -gt 0 ] 2> /dev/null && echo "--expect $s"
}

rc=0
t0=$(date +%s)
plan_out=$run/jobs.mk
[ "$scheduler" = slurm ] && plan_out=$run/submit.sh
step "$bin" plan "${scenes[@]}" --out "$run" --cache "$cache" --bin "$bin" $small --scheduler "$scheduler" > "$plan_out"
st=$?
if [ $st -ne 0 ]; then
    echo "reflcheck nightly: plan refused the scenes (exit $st); nothing rendered" >&2
    exit $st
fi
# Figure 1 (the Fresnel curves and gnuplot's figure) and each scene's own materials' Figure 1
# (the report's figure1-<scene>.html, one degree apart) need only the scenes and the program:
# made beside the renders (0.3 CPU-s, but 3.5 s of wall in a row of 38 short processes before the
# report when the machine is loaded); their messages are shown before the report.
(
    if [ -f tools/plots/figure1.gp ]; then
        for p in 2 4 5; do "$bin" eval fresnel --ior 1.5 --p $p --steps 900 > "$run/p$p.csv"; done
        gnuplot -e "dir='$run'" tools/plots/figure1.gp > /dev/null 2>&1 || echo "figure1 plot failed" >&2
    fi
    for s in "${scenes[@]}"; do
        "$bin" eval materials "$s" --out "$run" || echo "reflcheck nightly: $s: no Figure 1 of its materials" >&2
    done
) 2> "$run/.figures.err" &
figures_pid=$!
sweep_args=(--run "$run" --cache "$cache/sweep" --bin "$bin" --jobs "$jobs" --scenes "${scenes[@]}" ${SMALL:+--quick})
if [ "$scheduler" = make ]; then
    # make's own output goes to a file; the watch counts the job records as they land and names
    # a failed job at once.
    n=$(grep -c '^all: ' "$run/jobs.mk")
    say "renders: $n jobs, $jobs at a time (their output: $run/renders.txt)"
    # Cycles and EEVEE jobs hand their render to one of $jobs Blender workers each
    # (worker_pool.py; EEVEE's under one Xvfb, llvmpipe drawing with the jobs' threads), so
    # Blender starts once per worker, not once per job, and only at the first job the cache
    # does not answer; the workers stop with make.
    pool=()
    eevee_threads=$(sed -n 's/.*--renderer eevee .*--threads \([0-9]*\).*/\1/p' "$run/jobs.mk" | head -n1)
    grep -q -e "--renderer cycles " -e "--renderer eevee " "$run/jobs.mk" && command -v blender > /dev/null &&
        pool=(/usr/bin/python3 harness/renderers/cycles/worker_pool.py --workers "$jobs" --log-dir "$run"
            ${eevee_threads:+--eevee-threads "$eevee_threads"} --)
    # Two makes side by side, $jobs slots each: the plan's cpu jobs, and its wait jobs (POV-Ray,
    # about 1 s a job asleep in its own timers for 0.03-0.8 CPU-s), which would otherwise hold a
    # CPU slot while a core idles (as the sweep does, docs/sweep.md). Both append to renders.txt.
    {
        "${pool[@]}" make -k -j"$jobs" -f "$run/jobs.mk" cpu &
        cpu_mk=$!
        make -k -j"$jobs" -f "$run/jobs.mk" wait
        wait_st=$?
        wait "$cpu_mk" && exit $wait_st
    } > "$run/renders.txt" 2>&1 &
    mk=$!
    progress watch "$run" --total "$n" --pid "$mk" --label renders
    wait "$mk" || { say "some render jobs failed; see $run/renders.txt and the job records"; rc=1; }
    stage_done renders "$t0"
    t1=$(date +%s)
    echo "$((t1 - t0))" > "$run/render_wall_s"
    # Error against time (tools/sweep.py): quality knobs of every renderer on the scenes that list
    # cycles validate, small size, one thread per job, $jobs jobs at a time.
    # Its progress lines (stderr) go to this stderr and, with its output, to sweep.txt.
    if [ -z "${NO_SWEEP:-}" ]; then
        : > "$run/sweep.txt"
        step /usr/bin/python3 tools/sweep.py "${sweep_args[@]}" >> "$run/sweep.txt" \
            2> >(tee -a "$run/sweep.txt" >&2) ||
            { echo "reflcheck nightly: sweep failed; see $run/sweep.txt" >&2; rc=1; }
        stage_done sweep "$t1"
    fi
    # compare runs with the fits, below: both need only the renders.
else
    mkdir -p "$run/slurm"
    step bash "$run/submit.sh" > "$run/slurm/render_ids" 2> "$run/slurm/submit.err"
    st=$?
    cat "$run/slurm/submit.err" >&2
    deps=$(cat "$run/slurm/render_ids")
    if [ $st -ne 0 ] || [ -z "$deps" ]; then
        ids=$(slurm_jobs)
        # shellcheck disable=SC2086
        [ -n "$ids" ] && scancel $ids
        record_failed "submitting the render jobs to Slurm failed (exit $st): $(tail -n1 "$run/slurm/submit.err" 2>/dev/null)"
        exit 1
    fi
    if [ -z "${NO_SWEEP:-}" ]; then
        # One node, JOBS CPUs: the sweep's Blender workers and their srun steps share the node.
        sweep_id=$(sbatch --parsable -N1 -n1 -c "$jobs" --time="${SWEEP_MINUTES:-240}" --job-name=reflcheck-sweep \
            --output="$run/sweep.txt" ops/slurm/step.sh "$run/sweep.rc" \
            /usr/bin/python3 tools/sweep.py "${sweep_args[@]}" --scheduler slurm) ||
            { echo "reflcheck nightly: submitting the sweep to Slurm failed" >&2; rc=1; }
        sweep_id=${sweep_id%%;*}
        [ -n "$sweep_id" ] && { echo "$sweep_id" >> "$run/slurm/steps"; deps=$deps:$sweep_id; }
    fi
    compare_id=$(sbatch --parsable --dependency="afterany:$deps" -n1 -c1 --time=60 --job-name=reflcheck-compare \
        --output="$run/slurm/compare.out" ops/slurm/compare.sh "$run" "$bin" "${scenes[@]}" 2> "$run/slurm/submit.err")
    compare_id=${compare_id%%;*}
    if [ -z "$compare_id" ]; then
        ids=$(slurm_jobs)
        # shellcheck disable=SC2086
        [ -n "$ids" ] && scancel $ids
        record_failed "submitting the compare step to Slurm failed: $(tail -n1 "$run/slurm/submit.err" 2>/dev/null)"
        exit 1
    fi
    echo "$compare_id" >> "$run/slurm/steps"
    echo "reflcheck nightly: Slurm jobs: renders $(cut -d' ' -f1 "$run/slurm/arrays" | paste -sd' '), sweep ${sweep_id:--}, compare $compare_id"
    # While the compare job waits for the others: the render records as they land (a job Slurm
    # ended without one gets it from the compare job), then the sweep's lines from its output.
    slurm_wait "$compare_id" &
    waiter=$!
    n=$(cat "$run"/slurm/renders-*.jobs 2> /dev/null | wc -l)
    progress watch "$run" --total "$n" --pid "$waiter" --label renders
    stage_done renders "$t0"
    if [ -n "${sweep_id:-}" ]; then
        progress follow "$run/sweep.txt" --label sweep --pid "$waiter"
        stage_done sweep "$t0"
    fi
    if ! wait "$waiter"; then
        record_failed "Slurm stopped answering (squeue failed for 10 minutes) while job $compare_id was queued"
        exit 1
    fi
    t1=$(date +%s)
    echo "$((t1 - t0))" > "$run/render_wall_s"
    [ "$(cat "$run/slurm/finish.rc" 2>/dev/null)" = 0 ] ||
        { echo "reflcheck nightly: some render jobs failed; see $run/slurm/finish.txt" >&2; rc=1; }
    if [ -n "${sweep_id:-}" ] && [ "$(cat "$run/sweep.rc" 2>/dev/null)" != 0 ]; then
        echo "reflcheck nightly: sweep failed; see $run/sweep.txt" >&2
        rc=1
    fi
    st=$(cat "$run/compare.rc" 2>/dev/null || echo 1)
fi
# Under Slurm the compare job has run: its lines now. Locally compare runs beside the fits.
if [ "$scheduler" = slurm ]; then
    cat "$run/compare.txt"
    [ $st -ne 0 ] && { echo "reflcheck nightly: comparisons failed or errored (compare exit $st)" >&2; rc=1; }
fi
# The best each approximation can do (harness/fit.h): its parameters fitted to every validate
# reference, which the job cache hands back without rendering again, within the seeds' ranges
# (RUN/<scene>/fit.json) and within wide ones (fit-wide.json). A fit of unchanged inputs comes
# back from CACHE/fits (ops/fit_cache.sh).
: > "$run/fit.txt"
# One fit per scene and bounds, so that progress counts scenes and a failed fit is named at once;
# JOBS at a time (each fit's output kept whole in fit.txt, in this order). A scene's seed and wide
# fits read its validate records without writing them (cli/cli_fit.c), so they may run together.
fits=()
for bounds in seed wide; do
    for s in "${scenes[@]}"; do fits+=("$bounds"$'\t'"$s"); done
done
t2=$(date +%s)
# The longest fits first (the last run's fit seconds, else an estimate from the scene file:
# ops/fit_costs.py), so the stage does not end on one core; fit.txt keeps the items' order.
costs=()
if /usr/bin/python3 ops/fit_costs.py "$latest" $small -- "${fits[@]}" > "$run/fit-costs.txt"; then
    costs=(--costs "$run/fit-costs.txt")
else
    say "no fit costs (ops/fit_costs.py failed, above): the fits start in item order"
fi
# Locally the compare (through CACHE/compare: a scene of unchanged renders and scene file is not
# measured again, ops/compare_cache.sh), one scene a call, and the fits share JOBS slots: one
# byte each in a FIFO that both take from (as make's jobserver), so neither waits for the
# other's last item. The compare's CPU seconds are its subshell's `times`; stages.tsv gets a
# compare line (its wall from this start to its last scene) and a fits line (to the last fit).
slots=()
if [ "$scheduler" = make ]; then
    rm -f "$run/.slots" && mkfifo "$run/.slots" && exec {slot_fd}<> "$run/.slots" &&
        printf "%${jobs}s" '' | tr ' ' + >&"$slot_fd" && slots=(--slots "$run/.slots")
    (
        COMPARE_SLOTS=${slots[1]:-} COMPARE_JOBS=$jobs bash ops/compare_cache.sh "$cache" "$bin" "$run" "${scenes[@]}" > "$run/compare.txt"
        cst=$?
        date +%s > "$run/.compare-end"
        times > "$run/.compare-times"
        exit $cst
    ) &
    compare_pid=$!
fi
# shellcheck disable=SC2046
progress each --label fits --jobs "$jobs" "${slots[@]}" "${costs[@]}" --log "$run/fit.txt" $(expected fits) -- \
    bash ops/fit_cache.sh "$cache" "$bin" '{2}' "$run" '{1}' $small ::: "${fits[@]}"
fst=$?
compare_cpu=0
if [ "$scheduler" = make ]; then
    wait "$compare_pid"
    st=$?
    compare_cpu=$(cpu_of "$run/.compare-times" 1)
    printf 'compare\t%s\t%s\n' "$(($(cat "$run/.compare-end" 2> /dev/null || date +%s) - t2))" "$compare_cpu" >> "$run/stages.tsv"
    [ -n "${slot_fd:-}" ] && exec {slot_fd}>&-
    rm -f "$run/.slots" "$run/.compare-end" "$run/.compare-times"
    cat "$run/compare.txt"
    [ $st -ne 0 ] && { echo "reflcheck nightly: comparisons failed or errored (compare exit $st)" >&2; rc=1; }
fi
[ $fst -ne 0 ] && { echo "reflcheck nightly: a fit failed (exit $fst); see $run/fit.txt" >&2; rc=1; }
stage_done fits "$t2" "$compare_cpu"
cat "$run/fit.txt"
t2=$(date +%s)
: > "$run/stability.txt"
# The stability table reads no scene: the program alone (path, size, time) decides it, so an
# unchanged one takes it from CACHE/stability/<key>/.
stab=$cache/stability/$({ readlink -f "$bin"; stat -Lc '%s %Y' "$bin"; } | sha256sum | cut -c1-32)
if [ -f "$stab/ok" ] && cp "$stab/stability.json" "$stab/stability.txt" "$run/" 2> /dev/null; then
    say "stability: unchanged program, the table from $stab"
else
    # shellcheck disable=SC2046
    if progress each --label stability --log "$run/stability.txt" $(expected stability) -- \
        "$bin" stability --json "$run/stability.json" ::: table; then
        tmp=$(mkdir -p "$cache/stability" && mktemp -d "$cache/stability/tmp-XXXXXX") &&
            cp "$run/stability.json" "$run/stability.txt" "$tmp/" && : > "$tmp/ok" &&
            { mv -T "$tmp" "$stab" 2> /dev/null || rm -rf "$tmp"; }
    else
        echo "reflcheck nightly: stability failed; see $run/stability.txt" >&2
        rc=1
    fi
fi
stage_done stability "$t2"
wait "$figures_pid"
cat "$run/.figures.err" >&2 2> /dev/null
rm -f "$run/.figures.err"
t2=$(date +%s)
# shellcheck disable=SC2046
progress each --label report --log "$run/report.txt" $(expected report) -- /usr/bin/python3 tools/report.py \
    --run "$run" --history "$history" --commit "$commit" ${reference_history:+--reference-history "$reference_history"} \
    --latest "$latest" --cache "$cache/report" $screenshot ::: index.html ||
    { echo "reflcheck nightly: the report failed; see $run/report.txt" >&2; rc=1; }
stage_done report "$t2"
# A report that failed before it appended the run's line (a full disk): the run is still recorded.
grep -qF "\"run_id\":\"$id\"" "$history" 2> /dev/null ||
    { record_failed "the report failed before it recorded the run; see the messages above"; rc=1; }
echo "reflcheck nightly: report at $run/index.html ($latest/index.html); exit $rc"
exit $rc
