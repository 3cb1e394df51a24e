#!/usr/bin/env bash
# A real one-node Slurm cluster on this machine, for tests and laptops:
#   scripts/slurm_local.sh start    start munged, slurmctld, slurmd; wait until the node is idle
#   scripts/slurm_local.sh stop     cancel the jobs, stop the daemons, end what they left running
#   scripts/slurm_local.sh status   print each daemon's pid and the node's state (exit 1 when down)
#   scripts/slurm_local.sh env      print the `export SLURM_CONF=...` line the clients need
# All idempotent: start when started and stop when stopped do nothing and succeed; start after a
# daemon died starts just that one. Job state (ids, finished jobs) survives stop/start; delete the
# folder for a fresh cluster. Root (as in CI) or not: as root munged runs as the munge user and jobs
# may run as any user; as another user all daemons and jobs run as that user (tested as nobody).
#
# What it runs: the Debian 12 packages slurmctld, slurmd, slurm-client and munge (Slurm 22.05),
# installed with apt-get when missing (so the project's normal build, scripts/setup.sh, needs no
# Slurm). No systemd and no cgroups: each daemon is started by hand, daemonizes, and is found again
# and stopped through its pid file. Everything lives under one folder,
#   SLURM_LOCAL_DIR (default /tmp/pcdp-slurm):
#     slurm.conf          the configuration (rewritten at each start)
#     munge/              munge.key, munged's socket, pid, seed and log (owned by the munge user)
#     .lock               flock serializing start and stop
#     spool/ctld, spool/d StateSaveLocation and SlurmdSpoolDir
#     log/                slurmctld.log, slurmd.log, jobcomp.txt (one line per finished job)
#     run/                slurmctld.pid, slurmd.pid
# Clients (sbatch, squeue, scontrol) find the cluster through SLURM_CONF=$SLURM_LOCAL_DIR/slurm.conf;
# `start` and `env` print that line. Other settings:
#   SLURM_LOCAL_PORT     slurmctld's port (default 6817); slurmd uses the next one. Two clusters on
#                        one machine need different folders and ports; start refuses a port in use.
#   SLURM_LOCAL_CPUS     CPUs the node declares (default 8, more than this machine's cores)
#   SLURM_LOCAL_NODE     the node's name (default pcdp-node1)
#   SLURM_LOCAL_TIMEOUT  seconds each wait may take (default 60)
#
# Pitfalls of Debian 12 / Slurm 22.05 and how this script handles them:
# - munged's default socket and pid file live in /run/munge, which does not exist without systemd
#   (tmpfiles.d creates it at boot). Here munged gets --socket, --pid-file, --seed-file, --log-file
#   and --key-file under munge/, and slurm.conf says AuthInfo=socket=... (read by both auth/munge and
#   cred/munge), so /run/munge is neither needed nor touched.
# - munged refuses to run as root, and it refuses a key or directories that others may write. As
#   root it runs as the munge user (runuser -u munge) with munge/ owned by munge (mode 0711, so
#   clients reach the socket) and the key 0400; as another user it runs as that user.
# - The daemons must not need systemd or cgroups: ProctrackType=proctrack/linuxproc (process tree by
#   /proc), TaskPlugin=task/none, JobAcctGatherType=jobacct_gather/none, no cgroup.conf.
# - `kill_invalid_depend` is a DependencyParameters option (not SchedulerParameters, where 22.05
#   ignores it): with it a job whose afterok dependency failed ends CANCELLED with reason
#   DependencyNeverSatisfied instead of pending for ever.
# - `sbatch --wait` returns 0 for a job cancelled by a failed dependency: do not trust it; check each
#   job's state with `scontrol show job` (scripts/slurm_lib.sh: slurm_wait_jobs).
# - Batch jobs start on a 3 s tick by default: SchedulerParameters=batch_sched_delay=0 schedules
#   them at submission, sched_min_interval=0 removes the throttle between scheduling passes.
#   Even so the main scheduler runs on slurmctld's 1 s background tick (a job waits up to 1 s), and
#   its first cycle comes about 3 s after slurmctld starts: `start` waits for it (sdiag's "Total
#   cycles" >= 1), so the first job does not pay those 3 s.
# - Finished jobs disappear from scontrol after MinJobAge (300 s): MinJobAge=86400 keeps them
#   visible for a day.
# - There is no sacct without an accounting database (slurmdbd): use `scontrol show job`, or the
#   JobCompType=jobcomp/filetxt record in log/jobcomp.txt, which outlives the daemons.
# - Tests want parallel tasks on a small machine: the node declares SLURM_LOCAL_CPUS CPUs with
#   SlurmdParameters=config_overrides (otherwise slurmd registers the real count, or the node is
#   drained as INVALID), and SelectTypeParameters=CR_CPU so memory is not a consumed resource.
# - slurmctld only runs on the host named by SlurmctldHost, so that is this host's short name,
#   reached at 127.0.0.1; the node is named SLURM_LOCAL_NODE and slurmd is started with -N.
# - ReturnToService=2 so a node that was DOWN (e.g. slurmd killed) comes back when slurmd registers.
# - Stopping slurmd does not end the slurmstepd of running jobs: stop cancels the jobs first, and
#   every daemon is started with PCDP_SLURM_LOCAL_DIR in its environment (slurmstepd inherits it),
#   so stop finds and ends exactly this cluster's leftovers and nothing else.
# - The daemons must not inherit the lock's descriptor (flock on $DIR/.lock serializes start and
#   stop), else they hold the lock for ever: they are started with 9>&-.
# - Every wait has a deadline (SLURM_LOCAL_TIMEOUT); when start fails it prints the logs' tails.
set -euo pipefail

DIR="${SLURM_LOCAL_DIR:-/tmp/pcdp-slurm}"
PORT="${SLURM_LOCAL_PORT:-6817}"
CPUS="${SLURM_LOCAL_CPUS:-8}"
NODE="${SLURM_LOCAL_NODE:-pcdp-node1}"
TIMEOUT="${SLURM_LOCAL_TIMEOUT:-60}"
PACKAGES=(slurmctld slurmd slurm-client munge)

die() { echo "slurm_local: $*" >&2; exit 1; }
say() { echo "slurm_local: $*" >&2; }

case "$DIR" in /*) ;; *) DIR="$PWD/$DIR" ;; esac
MUNGE_DIR="$DIR/munge"
SOCKET="$MUNGE_DIR/munge.socket.2"
CONF="$DIR/slurm.conf"
export SLURM_CONF="$CONF"

ME="$(id -un)"
if [ "$(id -u)" -eq 0 ]; then ROOT=1; else ROOT=0; fi

install_packages() {
  local missing=() p
  for p in "${PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  [ ${#missing[@]} -eq 0 ] && return 0
  say "installing ${missing[*]}"
  local sudo=""
  if [ "$ROOT" -eq 0 ]; then
    command -v sudo >/dev/null || die "packages missing (${missing[*]}) and no sudo to install them"
    sudo="sudo"
  fi
  $sudo apt-get update -qq
  # policy-rc.d or not, the packages' own services are not used: this script starts its own daemons
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
}

# alive PID...: true when every PID is a live process (a zombie is not: PID 1 may be slow to reap it)
alive() {
  local p st
  for p in "$@"; do
    { read -r st <"/proc/$p/stat"; } 2>/dev/null || return 1
    st="${st##*) }"  # the state follows "(comm) ", and comm may hold blanks
    [ -n "$st" ] && [ "${st%% *}" != Z ] || return 1
  done
}
# any_alive PID...: true when one of the PIDs is a live process
any_alive() {
  local p
  for p in "$@"; do alive "$p" && return 0; done
  return 1
}

# pid_of NAME PIDFILE: the pid in PIDFILE when that process is alive and is NAME, else nothing
pid_of() {
  local name="$1" file="$2" pid
  [ -s "$file" ] || return 0
  pid="$(tr -dc 0-9 <"$file")"
  [ -n "$pid" ] && alive "$pid" || return 0
  [ "$(cat "/proc/$pid/comm" 2>/dev/null)" = "$name" ] && echo "$pid"
  return 0
}
# daemon_pid NAME PIDFILE: the daemon's pid, from its pid file, else (pid file not yet written, or
# lost) from the environment it was started with
daemon_pid() {
  local pid
  pid="$(pid_of "$1" "$2")"
  [ -n "$pid" ] || pid="$(our_processes "$1" | sort -n | head -n 1)"
  echo "$pid"
}
munged_pid() { daemon_pid munged "$MUNGE_DIR/munged.pid"; }
ctld_pid() { daemon_pid slurmctld "$DIR/run/slurmctld.pid"; }
slurmd_pid() { daemon_pid slurmd "$DIR/run/slurmd.pid"; }

# our_processes [NAME]: this cluster's processes (named NAME): those started with PCDP_SLURM_LOCAL_DIR=$DIR (slurmstepd inherits it)
our_processes() {
  local c comm pid
  for c in /proc/[0-9]*/comm; do
    { read -r comm <"$c"; } 2>/dev/null || continue
    case "$comm" in munged|slurmctld|slurmscriptd|slurmd|slurmstepd) ;; *) continue ;; esac
    [ -z "${1:-}" ] || [ "$comm" = "$1" ] || continue
    pid="${c#/proc/}"; pid="${pid%/comm}"
    grep -qazxF "PCDP_SLURM_LOCAL_DIR=$DIR" "/proc/$pid/environ" 2>/dev/null && echo "$pid"
  done
  return 0
}

# descendants PID: the pids of PID's children, grandchildren, ...
descendants() {
  ps -eo pid=,ppid= | awk -v root="$1" '
    { parent[$1] = $2 }
    END { for (p in parent) { q = parent[p]; while (q != "" && q != 0 && q != 1) { if (q == root) { print p; break } q = parent[q] } } }'
}

# wait_for SECONDS WHAT COMMAND...: run COMMAND every 0.1 s until it succeeds or the deadline passes
wait_for() {
  local secs="$1" what="$2"; shift 2
  local deadline=$((SECONDS + secs))
  until "$@" >/dev/null 2>&1; do
    [ $SECONDS -ge $deadline ] && { say "timed out after ${secs}s waiting for $what"; return 1; }
    sleep 0.1
  done
}

show_logs() {
  local f
  for f in "$MUNGE_DIR/munged.log" "$DIR/log/slurmctld.log" "$DIR/log/slurmd.log"; do
    [ -r "$f" ] || continue
    echo "----- tail of $f" >&2
    tail -n 25 "$f" >&2
  done
}

node_state() { scontrol show node "$NODE" -o 2>/dev/null | sed -n 's/.* State=\([^ ]*\).*/\1/p'; }
node_idle() { case "$(node_state)" in IDLE|IDLE+*) return 0 ;; *) return 1 ;; esac; }
port_free() { ! (exec 3<>"/dev/tcp/127.0.0.1/$1") 2>/dev/null; }
munge_works() { munge -n -S "$SOCKET" | unmunge -S "$SOCKET"; }
ctld_up() { scontrol ping | grep -q "is UP"; }
scheduler_live() { sdiag | awk '/^Main schedule statistics/ { m = 1 } m && /Total cycles:/ { exit !($3 >= 1) }'; }

write_conf() {
  local host; host="$(hostname -s)"
  cat >"$CONF" <<EOF
# written by scripts/slurm_local.sh; rewritten at each start
ClusterName=pcdp
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$PORT
SlurmdPort=$((PORT + 1))
SlurmUser=$ME
SlurmdUser=$ME
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$SOCKET
StateSaveLocation=$DIR/spool/ctld
SlurmdSpoolDir=$DIR/spool/d
SlurmctldPidFile=$DIR/run/slurmctld.pid
SlurmdPidFile=$DIR/run/slurmd.pid
SlurmctldLogFile=$DIR/log/slurmctld.log
SlurmdLogFile=$DIR/log/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/filetxt
JobCompLoc=$DIR/log/jobcomp.txt
MpiDefault=none
MailProg=/bin/true
SwitchType=switch/none
SchedulerType=sched/backfill
SchedulerParameters=batch_sched_delay=0,sched_min_interval=0
DependencyParameters=kill_invalid_depend
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SlurmdParameters=config_overrides
ReturnToService=2
MinJobAge=86400
KillWait=5
InactiveLimit=0
Waittime=0
NodeName=$NODE NodeHostname=$host NodeAddr=127.0.0.1 CPUs=$CPUS State=UNKNOWN
PartitionName=local Nodes=$NODE Default=YES MaxTime=INFINITE State=UP
EOF
}

start_munged() {
  [ -n "$(munged_pid)" ] && return 0
  mkdir -p "$MUNGE_DIR"
  chmod 0711 "$MUNGE_DIR"
  [ "$ROOT" -eq 1 ] && chown munge:munge "$MUNGE_DIR"
  if [ ! -s "$MUNGE_DIR/munge.key" ]; then
    (umask 077; dd if=/dev/urandom of="$MUNGE_DIR/munge.key" bs=1024 count=1 status=none)
  fi
  chmod 0400 "$MUNGE_DIR/munge.key"
  [ "$ROOT" -eq 1 ] && chown munge:munge "$MUNGE_DIR/munge.key"
  rm -f "$SOCKET" "$SOCKET.lock"
  local run=()
  [ "$ROOT" -eq 1 ] && run=(runuser -u munge --)
  "${run[@]}" env PCDP_SLURM_LOCAL_DIR="$DIR" munged \
    --socket="$SOCKET" --key-file="$MUNGE_DIR/munge.key" --pid-file="$MUNGE_DIR/munged.pid" \
    --seed-file="$MUNGE_DIR/munged.seed" --log-file="$MUNGE_DIR/munged.log" 9>&- \
    || { show_logs; die "munged did not start"; }
  wait_for "$TIMEOUT" "munged to answer on $SOCKET" munge_works || { show_logs; die "munged is not answering"; }
}

start() {
  install_packages
  mkdir -p "$DIR"
  exec 9>>"$DIR/.lock"
  flock -w "$TIMEOUT" 9 || die "another slurm_local.sh holds $DIR/.lock"
  chmod 0755 "$DIR"  # munged refuses a key under a folder others may write
  mkdir -p "$DIR/spool/ctld" "$DIR/spool/d" "$DIR/log" "$DIR/run"
  local fresh=0
  if [ -n "$(ctld_pid)" ] && [ -n "$(slurmd_pid)" ] && [ -n "$(munged_pid)" ]; then
    say "already running ($DIR)"
  else
    # ports in use by another cluster: refuse before starting anything
    [ -n "$(ctld_pid)" ] || port_free "$PORT" \
      || die "port $PORT (slurmctld) is in use, another cluster? set SLURM_LOCAL_PORT"
    [ -n "$(slurmd_pid)" ] || port_free $((PORT + 1)) \
      || die "port $((PORT + 1)) (slurmd) is in use, another cluster? set SLURM_LOCAL_PORT"
    [ -n "$(ctld_pid)$(slurmd_pid)" ] || write_conf
    start_munged
    if [ -z "$(ctld_pid)" ]; then
      fresh=1
      env PCDP_SLURM_LOCAL_DIR="$DIR" slurmctld -f "$CONF" 9>&- || { show_logs; die "slurmctld did not start"; }
    fi
    # (a daemon that exited ends the wait at once; daemon_pid finds it by its environment when its
    # pid file is not yet written: slurmd's parent returns before its child writes it)
    # shellcheck disable=SC2016  # eval'ed by wait_for at each try
    if ! wait_for "$TIMEOUT" "slurmctld to answer" eval '[ -z "$(ctld_pid)" ] || ctld_up' \
       || [ -z "$(ctld_pid)" ]; then
      show_logs
      die "slurmctld is not answering"
    fi
    if [ -z "$(slurmd_pid)" ]; then
      env PCDP_SLURM_LOCAL_DIR="$DIR" slurmd -f "$CONF" -N "$NODE" 9>&- || { show_logs; die "slurmd did not start"; }
    fi
  fi
  # shellcheck disable=SC2016  # eval'ed by wait_for at each try
  if ! wait_for "$TIMEOUT" "node $NODE to be idle" eval '[ -z "$(slurmd_pid)" ] || node_idle' \
     || [ -z "$(slurmd_pid)" ]; then
    scontrol show node "$NODE" >&2 || true
    show_logs
    die "node $NODE is not idle (state: $(node_state); slurmd: $(slurmd_pid))"
  fi
  if [ "$fresh" -eq 1 ] && ! wait_for "$TIMEOUT" "the main scheduler's first cycle" scheduler_live; then
    show_logs
    die "slurmctld's main scheduler has not run"
  fi
  say "node $NODE is $(node_state); clients need:"
  echo "export SLURM_CONF=$CONF"
}

# stop_pid NAME PID: SIGTERM, then SIGKILL once the deadline has passed
stop_pid() {
  local name="$1" pid="$2"
  [ -n "$pid" ] || return 0
  kill -TERM "$pid" 2>/dev/null || return 0
  if ! wait_for "$TIMEOUT" "$name ($pid) to exit" eval '! alive '"$pid"; then
    say "killing $name ($pid)"
    kill -KILL "$pid" 2>/dev/null || true
    wait_for 10 "$name ($pid) to die" eval '! alive '"$pid" || true
  fi
}

stop() {
  [ -d "$DIR" ] || { say "not running ($DIR does not exist)"; return 0; }
  exec 9>>"$DIR/.lock"
  flock -w "$TIMEOUT" 9 || die "another slurm_local.sh holds $DIR/.lock"
  if [ -n "$(ctld_pid)" ] && [ -n "$(munged_pid)" ]; then
    local jobs
    jobs="$(squeue -h -o %i 2>/dev/null | tr '\n' ' ')" || true
    if [ -n "${jobs// }" ]; then
      say "cancelling jobs: $jobs"
      # shellcheck disable=SC2086
      scancel $jobs 2>/dev/null || true
      # shellcheck disable=SC2016  # run by bash -c at each try
      wait_for "$TIMEOUT" "the jobs to end" bash -c '[ -z "$(squeue -h -o %i)" ]' || true
    fi
  fi
  local d c m
  d="$(slurmd_pid)"; c="$(ctld_pid)"; m="$(munged_pid)"
  # all at once (each takes a second or two to exit), then wait for each with the deadline
  # shellcheck disable=SC2086  # each may be empty
  kill -TERM $d $c $m 2>/dev/null || true
  stop_pid slurmd "$d"
  stop_pid slurmctld "$c"
  stop_pid munged "$m"
  # leftovers (a slurmstepd whose job could not be cancelled, e.g. slurmctld was dead): end the job's
  # processes (its descendants, which do not carry the variable), then slurmstepd, which ignores TERM
  local left pid tree
  left="$(our_processes)"
  for pid in $left; do
    tree="$(descendants "$pid" | tr '\n' ' ')"
    say "ending leftover $(cat "/proc/$pid/comm" 2>/dev/null) ($pid) and its processes ${tree:-(none)}"
    # shellcheck disable=SC2086  # a list of pids
    kill -TERM $tree 2>/dev/null || true
    # shellcheck disable=SC2086
    wait_for 5 "the processes of $pid to exit" eval "! any_alive $tree" \
      || kill -KILL $tree 2>/dev/null || true
    kill -KILL "$pid" 2>/dev/null || true
    wait_for 10 "$pid to die" eval "! alive $pid" || true
  done
  rm -f "$DIR/run/slurmctld.pid" "$DIR/run/slurmd.pid" "$SOCKET" "$SOCKET.lock"
  left="$(our_processes)"
  [ -z "$left" ] || die "still running after stop: $left"
  say "stopped ($DIR)"
}

status() {
  local m c d rc=0
  m="$(munged_pid)"; c="$(ctld_pid)"; d="$(slurmd_pid)"
  echo "dir: $DIR"
  echo "munged: ${m:-not running}"
  echo "slurmctld: ${c:-not running}"
  echo "slurmd: ${d:-not running}"
  if [ -n "$c" ] && [ -n "$m" ]; then
    echo "node $NODE: $(node_state || true)"
    [ -n "$d" ] || rc=1
  else
    echo "node $NODE: down"
    rc=1
  fi
  return $rc
}

case "${1:-}" in
  start) start ;;
  stop) stop ;;
  status) status ;;
  env) echo "export SLURM_CONF=$CONF" ;;
  *) echo "usage: $0 start|stop|status|env" >&2; exit 2 ;;
esac
