#!/usr/bin/env bash
# A single-node Slurm cluster on this machine, for trying `--executor slurm` on a laptop and for CI.
#
#   scripts/local-slurm.sh start   # needs root and Debian's slurmctld slurmd slurm-client munge
#   scripts/local-slurm.sh stop    # stops exactly the daemons `start` started, by their PIDs
#
# Everything (config, state, logs, PID files) lives under $BFQI_SLURM_DIR (default /tmp/bfqi-slurm).
# No systemd is needed. The controller and the node are this host.
set -euo pipefail
dir="${BFQI_SLURM_DIR:-/tmp/bfqi-slurm}"
conf="$dir/slurm.conf"

start() {
  for cmd in munged slurmctld slurmd sbatch; do
    command -v "$cmd" >/dev/null || { echo "missing $cmd: apt-get install slurmctld slurmd slurm-client munge" >&2; exit 1; }
  done
  mkdir -p "$dir"/{state,spool,log}
  # munge: a key, and a daemon with its own socket and PID file.
  mkdir -p /etc/munge /var/run/munge /var/lib/munge /var/log/munge
  if [ ! -s /etc/munge/munge.key ]; then
    dd if=/dev/urandom bs=1 count=1024 of=/etc/munge/munge.key 2>/dev/null
  fi
  chown -R munge:munge /etc/munge /var/run/munge /var/lib/munge /var/log/munge 2>/dev/null || true
  chmod 0400 /etc/munge/munge.key
  if ! munge -n >/dev/null 2>&1; then
    runuser -u munge -- munged --pid-file="$dir/munged.pid" 2>/dev/null || munged -f --pid-file="$dir/munged.pid"
    for _ in $(seq 50); do munge -n >/dev/null 2>&1 && break; sleep 0.1; done
    [ -f "$dir/munged.pid" ] || pgrep -n munged > "$dir/munged.pid"
  fi
  host=$(hostname -s)
  node=$(slurmd -C | head -n 1)
  cat > "$conf" <<CONF
ClusterName=bfqi
SlurmctldHost=$host
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/backfill
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
ReturnToService=2
MpiDefault=none
JobCompType=jobcomp/none
AccountingStorageType=accounting_storage/none
$node State=UNKNOWN
PartitionName=debug Nodes=ALL Default=YES MaxTime=INFINITE State=UP
CONF
  export SLURM_CONF="$conf"
  slurmctld -f "$conf"
  slurmd -f "$conf"
  for _ in $(seq 100); do
    if sinfo -h -o %t 2>/dev/null | grep -qE '^(idle|mix|alloc)'; then
      echo "local Slurm cluster up (SLURM_CONF=$conf)"
      sinfo
      return 0
    fi
    sleep 0.2
  done
  echo "Slurm did not come up; logs in $dir/log" >&2
  tail -n 20 "$dir"/log/*.log >&2 || true
  exit 1
}

stop() {
  for d in slurmd slurmctld munged; do
    if [ -f "$dir/$d.pid" ]; then
      pid=$(cat "$dir/$d.pid")
      kill "$pid" 2>/dev/null || true
      for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
      rm -f "$dir/$d.pid"
    fi
  done
  echo "local Slurm cluster stopped"
}

case "${1:-}" in
  start) start ;;
  stop) stop ;;
  *) echo "usage: $0 start|stop" >&2; exit 2 ;;
esac
