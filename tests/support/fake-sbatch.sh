#!/usr/bin/env bash
# A stand-in for `sbatch --wait --array=...` that runs the array's tasks one after another on this
# machine, for testing the Slurm executor's driver without a cluster. Fault injection:
#   FAKE_SBATCH_DROP_ONCE=K    task K of the first submission is lost (as if its node died)
#   FAKE_SBATCH_DROP_ALWAYS=K  task K of every submission is lost
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
  SLURM_ARRAY_TASK_ID=$k bash "$script" >"$log" 2>&1 || status=1
done
exit $status
