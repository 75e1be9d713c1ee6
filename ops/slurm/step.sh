#!/usr/bin/env bash
# A nightly step as a Slurm batch job: runs CMD ARG..., writes its exit status to RCFILE (on the
# shared run folder, where the nightly reads it), and exits with it.
#   sbatch ... ops/slurm/step.sh RCFILE CMD [ARG...]
set -uo pipefail
rcfile=${1:?usage: step.sh RCFILE CMD [ARG...]}
shift
"$@"
rc=$?
echo "$rc" > "$rcfile"
exit "$rc"
