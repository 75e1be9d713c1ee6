#!/usr/bin/env bash
# One render job of a reflcheck plan as a Slurm array task. The submit script that
# `reflcheck plan --scheduler slurm` writes runs
#   sbatch --array=0-N ... ops/slurm/task.sh RUN/slurm/renders-G.jobs
# and task K runs line K + 1 of the list: the job's record path, then its `reflcheck run`
# command, as shell words. The job's exit status is the task's, its output the task's
# Slurm output file (RUN/slurm/<array>_<task>.out). A job Slurm ends before it writes its
# record gets one from ops/slurm/finish.py.
set -uo pipefail
list=${1:?usage: task.sh LIST (run by sbatch --array)}
task=${SLURM_ARRAY_TASK_ID:?task.sh runs as a Slurm array task (sbatch --array)}
line=$(sed -n "$((task + 1))p" "$list")
if [ -z "$line" ]; then
    echo "reflcheck task: $list has no line $((task + 1)); submit the list again with its plan" >&2
    exit 2
fi
# The line holds single-quoted words only (reflcheck plan quotes every path).
eval "words=($line)"
exec "${words[@]:1}"
