#!/usr/bin/env bash
# A real single-node Slurm on this machine, for sandswim's Slurm tests and for developers:
#   deploy/slurm/local-cluster.sh start    munge + slurmctld + slurmd, waits until the node is idle
#   deploy/slurm/local-cluster.sh stop     stops the three daemons (state in /var/lib/slurm stays)
#   deploy/slurm/local-cluster.sh status   exit 0 when the node answers sinfo as idle/mixed/alloc
# Runs as root, without systemd (containers, CI). Needs Debian 12's slurmctld slurmd slurm-client
# munge (deploy/install-deps.sh installs them). It writes /etc/slurm/slurm.conf only when that file
# is missing or was written by this script (a real site's configuration is never touched).
#
# Facts behind each step (Slurm 22.05, Debian 12, found the hard way):
# - munged must run as user munge and needs /run/munge; the package created the key.
# - slurmd refuses a node whose NodeName line differs from the machine: take it from `slurmd -C`,
#   with RealMemory a little under `free -m`; the node name must resolve.
# - The daemons run as user slurm and cannot delete their stale /run/*.pid: remove them first.
# - batch_sched_delay=0, else jobs start on 3-second ticks; EnforcePartLimits=ALL, else an
#   oversized job pends forever instead of being refused at sbatch.
# - MpiDefault=pmix: Debian's Open MPI works under `srun --mpi=pmix` (pmi2/none fail).
set -euo pipefail

CONF=/etc/slurm/slurm.conf
MARKER="# written by sandswim deploy/slurm/local-cluster.sh"
LOG_DIR=/var/log/slurm

die() { echo "local-cluster: $*" >&2; exit 1; }

need_root() { [ "$(id -u)" -eq 0 ] || die "run as root (it starts munged, slurmctld and slurmd)"; }

need_tools() {
  local missing=()
  for t in munged slurmctld slurmd sinfo sbatch squeue scontrol; do
    command -v "$t" >/dev/null 2>&1 || [ -x "/usr/sbin/$t" ] || missing+=("$t")
  done
  [ ${#missing[@]} -eq 0 ] || die "missing ${missing[*]}: run deploy/install-deps.sh (slurmctld slurmd slurm-client munge)"
}

node_line() {
  local mem line
  mem=$(free -m | awk '/^Mem:/ {print $2}')
  mem=$(( mem * 9 / 10 ))  # a little under what the node reports, or slurmd refuses it
  line=$(/usr/sbin/slurmd -C | head -n 1)
  echo "$line" | sed -E "s/RealMemory=[0-9]+/RealMemory=${mem}/"
}

write_conf() {
  if [ -f "$CONF" ] && ! grep -qF "$MARKER" "$CONF"; then
    echo "local-cluster: keeping the existing $CONF (not written by this script)" >&2
    return
  fi
  local host node
  host=$(hostname -s)
  getent hosts "$host" >/dev/null || die "the host name '$host' does not resolve (add it to /etc/hosts)"
  node=$(node_line)
  mkdir -p /etc/slurm
  cat > "$CONF.tmp" <<EOF
$MARKER
ClusterName=sandswim-local
SlurmctldHost=$host
SlurmUser=slurm
AuthType=auth/munge
StateSaveLocation=/var/lib/slurm/slurmctld
SlurmdSpoolDir=/var/lib/slurm/slurmd
SlurmctldPidFile=/run/slurmctld.pid
SlurmdPidFile=/run/slurmd.pid
SlurmctldLogFile=$LOG_DIR/slurmctld.log
SlurmdLogFile=$LOG_DIR/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
MpiDefault=pmix
SchedulerType=sched/backfill
SchedulerParameters=batch_sched_delay=0
EnforcePartLimits=ALL
ReturnToService=2
MailProg=/bin/true
JobCompType=jobcomp/filetxt
JobCompLoc=$LOG_DIR/jobcomp.txt
MinJobAge=300
KillWait=30
SlurmctldTimeout=30
SlurmdTimeout=60
InactiveLimit=0
$node State=UNKNOWN
PartitionName=debug Nodes=ALL Default=YES MaxTime=INFINITE State=UP
EOF
  mv "$CONF.tmp" "$CONF"
}

start_munge() {
  if pgrep -u munge -x munged >/dev/null; then return; fi
  install -d -o munge -g munge -m 0755 /run/munge
  runuser -u munge -- /usr/sbin/munged
}

wait_for() {  # wait_for SECONDS DESCRIPTION COMMAND...
  local seconds=$1 what=$2
  shift 2
  local deadline=$(( $(date +%s) + seconds ))
  until "$@" >/dev/null 2>&1; do
    [ "$(date +%s)" -lt "$deadline" ] || return 1
    sleep 0.2
  done
}

node_ready() {
  local state
  state=$(sinfo -h -N -o %t 2>/dev/null | head -n 1)
  case "$state" in idle|mix|alloc|comp) return 0 ;; *) return 1 ;; esac
}

start() {
  need_root
  need_tools
  write_conf
  install -d -o slurm -g slurm /var/lib/slurm /var/lib/slurm/slurmctld /var/lib/slurm/slurmd "$LOG_DIR"
  start_munge
  wait_for 10 "munge" munge -n || die "munged did not start (see /var/log/munge/munged.log)"
  if ! pgrep -x slurmctld >/dev/null; then
    rm -f /run/slurmctld.pid
    /usr/sbin/slurmctld
  fi
  if ! pgrep -x slurmd >/dev/null; then
    rm -f /run/slurmd.pid
    /usr/sbin/slurmd
  fi
  if ! wait_for 60 "node" node_ready; then
    # A node left down/drained by an earlier run comes back here.
    scontrol update NodeName="$(hostname -s)" State=RESUME >/dev/null 2>&1 || true
    wait_for 30 "node" node_ready || die "the node did not become idle: $(sinfo -N 2>&1 | tail -n 1); see $LOG_DIR/slurmd.log and slurmctld.log"
  fi
  echo "local-cluster: up ($(sinfo -h -N -o '%N %c CPUs %t'))"
}

stop_daemon() {  # stop_daemon NAME
  local pid
  pid=$(pgrep -x "$1" || true)
  [ -n "$pid" ] || return 0
  kill $pid 2>/dev/null || true
  for _ in $(seq 1 50); do
    kill -0 $pid 2>/dev/null || return 0
    sleep 0.1
  done
  kill -9 $pid 2>/dev/null || true
}

stop() {
  need_root
  # Jobs still running would be orphaned without their slurmd.
  scancel --full --quiet --state=RUNNING 2>/dev/null || true
  scancel --quiet --state=PENDING 2>/dev/null || true
  stop_daemon slurmd
  stop_daemon slurmctld
  local pid
  pid=$(pgrep -u munge -x munged || true)
  [ -z "$pid" ] || kill $pid 2>/dev/null || true
  rm -f /run/slurmctld.pid /run/slurmd.pid
  echo "local-cluster: stopped"
}

case "${1:-}" in
  start) start ;;
  stop) stop ;;
  status) node_ready ;;
  *) echo "usage: $0 start|stop|status" >&2; exit 2 ;;
esac
