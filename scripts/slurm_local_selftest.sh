#!/usr/bin/env bash
# Self-test of scripts/slurm_local.sh and scripts/slurm_lib.sh on a real one-node cluster:
#  1. start the cluster (its own folder and ports, so it does not meet one started by hand);
#  2. a 3-task array (each task writes $SLURM_ARRAY_TASK_ID to a file) and a job depending on it
#     (afterok) that checks the three files: all four must end COMPLETED;
#  3. the same with task 1 exiting 1: the dependent job must end CANCELLED, reason
#     DependencyNeverSatisfied, without having run;
#  4. stop the cluster: none of its processes (munged, slurmctld, slurmd, slurmstepd) may be left.
# Prints the time of each phase and the latency from submission to a task running.
#   SLURM_LOCAL_DIR   default /tmp/pcdp-slurm-selftest;  SLURM_LOCAL_PORT  default 6827
#   SLURM_WAIT_TIMEOUT  deadline of each wait for jobs (default 120 s)
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
export SLURM_LOCAL_DIR="${SLURM_LOCAL_DIR:-/tmp/pcdp-slurm-selftest}"
export SLURM_LOCAL_PORT="${SLURM_LOCAL_PORT:-6827}"
export SLURM_WAIT_TIMEOUT="${SLURM_WAIT_TIMEOUT:-120}"
# shellcheck source=scripts/slurm_lib.sh
. "$here/slurm_lib.sh"

now() { date +%s.%N; }
since() { awk -v a="$1" -v b="$(now)" 'BEGIN { printf "%.2f", b - a }'; }
fail() { echo "selftest: FAIL: $*" >&2; exit 1; }
t_all="$(now)"

"$here/slurm_local.sh" stop >/dev/null 2>&1 || true   # a clean start: no leftover from a killed run
trap '"$here/slurm_local.sh" stop >/dev/null 2>&1 || true' EXIT
t="$(now)"
"$here/slurm_local.sh" start >/dev/null
echo "selftest: cluster started in $(since "$t") s"
eval "$("$here/slurm_local.sh" env)"
"$here/slurm_local.sh" status

work="$SLURM_LOCAL_DIR/selftest"
rm -rf "$work"; mkdir -p "$work"
cat >"$work/task.sh" <<'EOF'
#!/bin/bash
# task.sh OUT FAIL_TASK: record the start time and the task id; task FAIL_TASK exits 1
date +%s.%N >"$1/start.$SLURM_ARRAY_TASK_ID"
echo "$SLURM_ARRAY_TASK_ID" >"$1/task.$SLURM_ARRAY_TASK_ID"
date +%s.%N >"$1/end.$SLURM_ARRAY_TASK_ID"
[ "$SLURM_ARRAY_TASK_ID" != "$2" ] || exit 1
EOF
cat >"$work/check.sh" <<'EOF'
#!/bin/bash
# check.sh OUT: the three tasks' files hold their ids; leaves OUT/check.ran
date +%s.%N >"$1/check.start"
for i in 0 1 2; do [ "$(cat "$1/task.$i")" = "$i" ] || { echo "task.$i missing or wrong" >&2; exit 1; }; done
touch "$1/check.ran"
EOF

# run NAME FAIL_TASK: submits the array and the dependent job; sets ARRAY, DEP, OUT, T_SUBMIT
run() {
  OUT="$work/$1"; mkdir -p "$OUT"
  T_SUBMIT="$(now)"
  ARRAY="$(sbatch --parsable --array=0-2 -J "st-$1" -o "$OUT/slurm-%A_%a.out" "$work/task.sh" "$OUT" "$2")"
  DEP="$(sbatch --parsable --dependency="afterok:$ARRAY" -J "st-$1-check" -o "$OUT/slurm-%j.out" "$work/check.sh" "$OUT")"
  echo "selftest: $1: array $ARRAY, dependent $DEP"
}

# latencies OUT T_SUBMIT: submit -> each task running; last task's end -> dependent running
latencies() {
  local i s first="" last="" e maxend=0
  for i in 0 1 2; do
    s="$(cat "$1/start.$i")"
    first="$(awk -v a="$s" -v b="${first:-$s}" 'BEGIN { print (a < b ? a : b) }')"
    last="$(awk -v a="$s" -v b="${last:-$s}" 'BEGIN { print (a > b ? a : b) }')"
    e="$(cat "$1/end.$i")"; maxend="$(awk -v a="$e" -v b="$maxend" 'BEGIN { print (a > b ? a : b) }')"
  done
  awk -v t="$2" -v f="$first" -v l="$last" 'BEGIN { printf "selftest: submit -> running: first task %.3f s, last task %.3f s\n", f - t, l - t }'
  if [ -f "$1/check.start" ]; then
    awk -v e="$maxend" -v c="$(cat "$1/check.start")" 'BEGIN { printf "selftest: last array task ended -> dependent job running: %.3f s\n", c - e }'
  fi
}

# --- 1: all succeed
t="$(now)"
run ok none
if ! states="$(slurm_wait_jobs "$ARRAY" "$DEP")"; then
  echo "$states"; cat "$OUT"/slurm-*.out 2>/dev/null || true; fail "run ok: a job did not complete"
fi
echo "$states"
[ "$(grep -c ' COMPLETED ' <<<"$states")" -eq 4 ] || fail "run ok: expected 4 COMPLETED tasks"
[ -f "$OUT/check.ran" ] || fail "run ok: the dependent job did not run"
echo "selftest: run ok passed in $(since "$t") s"
latencies "$OUT" "$T_SUBMIT"

# --- 2: task 1 fails; the dependent job is cancelled, never run
t="$(now)"
run fail 1
rc=0; states="$(slurm_wait_jobs "$ARRAY" "$DEP")" || rc=$?
echo "$states"
[ $rc -eq 1 ] || fail "run fail: slurm_wait_jobs returned $rc, expected 1"
grep -qx "${ARRAY}_0 COMPLETED .*" <<<"$states" || fail "run fail: task 0 should be COMPLETED"
grep -qx "${ARRAY}_1 FAILED .*exit=1:0" <<<"$states" || fail "run fail: task 1 should be FAILED with exit 1"
grep -qx "${ARRAY}_2 COMPLETED .*" <<<"$states" || fail "run fail: task 2 should be COMPLETED"
grep -qx "$DEP CANCELLED reason=DependencyNeverSatisfied .*" <<<"$states" \
  || fail "run fail: the dependent job should be CANCELLED with reason DependencyNeverSatisfied"
[ ! -e "$OUT/check.start" ] || fail "run fail: the dependent job ran"
echo "selftest: run fail passed in $(since "$t") s"
latencies "$OUT" "$T_SUBMIT"

# --- jobcomp/filetxt keeps a record of each finished job
[ "$(grep -c "JobId=" "$SLURM_LOCAL_DIR/log/jobcomp.txt")" -ge 4 ] || fail "log/jobcomp.txt lacks the finished jobs"

# --- 4: stop; nothing of this cluster left
t="$(now)"
"$here/slurm_local.sh" stop
trap - EXIT
left=""
for c in /proc/[0-9]*/comm; do
  { read -r comm <"$c"; } 2>/dev/null || continue
  case "$comm" in munged|slurmctld|slurmscriptd|slurmd|slurmstepd) ;; *) continue ;; esac
  pid="${c#/proc/}"; pid="${pid%/comm}"
  if grep -qazxF "PCDP_SLURM_LOCAL_DIR=$SLURM_LOCAL_DIR" "/proc/$pid/environ" 2>/dev/null; then left="$left $pid($comm)"; fi
done
[ -z "$left" ] || fail "processes left after stop:$left"
for f in munge/munged.pid run/slurmctld.pid run/slurmd.pid; do
  p="$(cat "$SLURM_LOCAL_DIR/$f" 2>/dev/null || true)"
  [ -z "$p" ] || [ ! -e "/proc/$p" ] || fail "$f: $p still running"
done
others="$(ps -eo pid=,stat=,comm= | awk '$2 !~ /^Z/ && $3 ~ /^(munged|slurmctld|slurmscriptd|slurmd|slurmstepd)$/ { print $1 "(" $3 ")" }' | tr '\n' ' ')"
[ -z "$others" ] || echo "selftest: note: other Slurm/munge processes on this machine (not this cluster's): $others"
"$here/slurm_local.sh" stop >/dev/null 2>&1 || fail "a second stop failed"
echo "selftest: cluster stopped in $(since "$t") s"
echo "selftest: PASS in $(since "$t_all") s"
