#!/usr/bin/env bash
# The nightly's compare step as a Slurm batch job, submitted with --dependency=afterany on every
# render (and the sweep): first the records of the jobs Slurm ended before they wrote their own
# (finish.py; its exit status goes to RUN/slurm/finish.rc), then the comparisons, as the local
# nightly runs them (RUN/compare.txt, exit status in RUN/compare.rc).
#   sbatch ... ops/slurm/compare.sh RUN BIN SCENE...
set -uo pipefail
run=${1:?usage: compare.sh RUN BIN SCENE...}
bin=${2:?usage: compare.sh RUN BIN SCENE...}
shift 2
/usr/bin/python3 ops/slurm/finish.py "$run" > "$run/slurm/finish.txt" 2>&1
echo $? > "$run/slurm/finish.rc"
"$bin" compare "$@" --run "$run" > "$run/compare.txt"
rc=$?
echo "$rc" > "$run/compare.rc"
exit "$rc"
