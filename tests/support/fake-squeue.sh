#!/usr/bin/env bash
# A stand-in for `squeue -h -j JOB -o %T` beside fake-sbatch.sh: RUNNING while the task that
# FAKE_SBATCH_DETACH_ONCE left behind still runs, nothing otherwise.
job=""
while [ $# -gt 0 ]; do
  case "$1" in
    -j) job="$2"; shift 2 ;;
    *) shift ;;
  esac
done
live="${FAKE_SBATCH_STATE:-/nonexistent}/live-$job"
if [ -f "$live" ] && kill -0 "$(cat "$live")" 2>/dev/null; then
  echo RUNNING
fi
exit 0
