#!/usr/bin/env bash
# A stand-in for `sbatch --wait --array=...` that runs the array's tasks one after another on this
# machine, for testing the Slurm executor's driver without a cluster. Fault injection:
#   FAKE_SBATCH_DROP_ONCE=K    task K of the first submission is lost (as if its node died)
#   FAKE_SBATCH_DROP_ALWAYS=K  task K of every submission is lost
#   FAKE_SBATCH_UNREACHABLE=N  the first N submissions fail as if the controller were down
#   FAKE_SBATCH_DETACH_ONCE=K  task K of the first submission is left running after sbatch returns
#                              (as when sbatch --wait loses its controller); fake-squeue.sh lists it
#   FAKE_SBATCH_STATE=DIR      where the first submission is remembered
set -u
array="" output="" script=""
for a in "$@"; do
  case "$a" in
    --array=*) array="${a#--array=}" ;;
    --output=*) output="${a#--output=}" ;;
    --*) ;;
    *) script="$a" ;;
  esac
done
range="${array%%%*}"
last="${range#*-}"
job=$$
if [ -n "${FAKE_SBATCH_UNREACHABLE:-}" ] && [ -n "${FAKE_SBATCH_STATE:-}" ]; then
  mkdir -p "$FAKE_SBATCH_STATE"
  n=$(cat "$FAKE_SBATCH_STATE/unreachable" 2>/dev/null || echo 0)
  if [ "$n" -lt "$FAKE_SBATCH_UNREACHABLE" ]; then
    echo $((n + 1)) > "$FAKE_SBATCH_STATE/unreachable"
    echo "sbatch: error: Batch job submission failed: Unable to contact slurm controller (connect failure)" >&2
    exit 1
  fi
fi
echo "Submitted batch job $job"
first=0
if [ -n "${FAKE_SBATCH_STATE:-}" ] && [ ! -e "$FAKE_SBATCH_STATE/submitted" ]; then
  first=1
  mkdir -p "$FAKE_SBATCH_STATE" && touch "$FAKE_SBATCH_STATE/submitted"
fi
status=0
for k in $(seq 0 "$last"); do
  if [ "${FAKE_SBATCH_DROP_ALWAYS:-x}" = "$k" ]; then continue; fi
  if [ "$first" = 1 ] && [ "${FAKE_SBATCH_DROP_ONCE:-x}" = "$k" ]; then continue; fi
  log="${output//%A/$job}"
  log="${log//%a/$k}"
  if [ "$first" = 1 ] && [ "${FAKE_SBATCH_DETACH_ONCE:-x}" = "$k" ]; then
    (sleep 1; SLURM_ARRAY_TASK_ID=$k bash "$script" >"$log" 2>&1) >/dev/null 2>&1 &
    echo $! > "$FAKE_SBATCH_STATE/live-$job"
    continue
  fi
  SLURM_ARRAY_TASK_ID=$k bash "$script" >"$log" 2>&1 || status=1
done
exit $status
