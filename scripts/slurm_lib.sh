# shellcheck shell=bash
# Bash helpers for Slurm jobs; source it: `. scripts/slurm_lib.sh`. Needs scontrol and SLURM_CONF
# (scripts/slurm_local.sh env) or a configured cluster; no sacct (no accounting database needed).

# slurm_wait_jobs [-t SECONDS] JOBID...
#   Waits until every task of the given jobs (array jobs expand to one line per task) has ended,
#   polling `scontrol show job` (not `sbatch --wait`, which returns 0 for a job cancelled because
#   its dependency failed). Prints one line per task on stdout:
#     <jobid or arrayjobid_taskid> <STATE> reason=<Reason> exit=<ExitCode>
#   Returns 0 when all tasks are COMPLETED, 1 when any ended otherwise or is unknown to slurmctld
#   (e.g. purged after MinJobAge), 124 when the deadline (-t, else SLURM_WAIT_TIMEOUT, else 600 s)
#   passed first (then the lines show the states at that time).
slurm_wait_jobs() {
  local timeout="${SLURM_WAIT_TIMEOUT:-600}"
  if [ "${1:-}" = "-t" ]; then timeout="${2:?slurm_wait_jobs: -t needs seconds}"; shift 2; fi
  if [ $# -eq 0 ]; then echo "usage: slurm_wait_jobs [-t SECONDS] JOBID..." >&2; return 2; fi
  local deadline=$((SECONDS + timeout)) id out line name state reason code busy rc
  local -a report
  while :; do
    busy=0; rc=0; report=()
    for id in "$@"; do
      if ! out="$(scontrol show job -o "$id" 2>&1)"; then
        case "$out" in
          *"Invalid job id"*) report+=("$id UNKNOWN reason=not-known-to-slurmctld exit=-"); rc=1; continue ;;
          *) busy=1; report+=("$id ? reason=scontrol-failed:${out//[$'\n ']/_} exit=-"); continue ;;  # slurmctld busy or restarting: retry
        esac
      fi
      while IFS= read -r line; do
        [ -n "$line" ] || continue
        name="$(_slurm_field JobId "$line")"
        if [ -n "$(_slurm_field ArrayJobId "$line")" ]; then
          name="$(_slurm_field ArrayJobId "$line")_$(_slurm_field ArrayTaskId "$line")"
        fi
        state="$(_slurm_field JobState "$line")"
        reason="$(_slurm_field Reason "$line")"
        code="$(_slurm_field ExitCode "$line")"
        report+=("$name $state reason=$reason exit=$code")
        case "$state" in
          COMPLETED) ;;
          FAILED|CANCELLED|TIMEOUT|NODE_FAIL|PREEMPTED|BOOT_FAIL|DEADLINE|OUT_OF_MEMORY|REVOKED|SPECIAL_EXIT) rc=1 ;;
          *) busy=1 ;;  # PENDING, RUNNING, CONFIGURING, COMPLETING, SUSPENDED, REQUEUED, ...
        esac
      done <<<"$out"
    done
    if [ $busy -eq 0 ]; then
      printf '%s\n' "${report[@]}"
      return $rc
    fi
    if [ $SECONDS -ge $deadline ]; then
      printf '%s\n' "${report[@]}"
      echo "slurm_wait_jobs: timed out after ${timeout}s waiting for $*" >&2
      return 124
    fi
    sleep 0.5
  done
}

# _slurm_field NAME LINE: the value of NAME=value in a one-line `scontrol show job -o` record
_slurm_field() {
  local re="(^| )$1=([^ ]*)"
  [[ $2 =~ $re ]] && printf '%s' "${BASH_REMATCH[2]}"
  return 0
}
