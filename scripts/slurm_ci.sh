#!/usr/bin/env bash
# CI test of sharded runs on a real (one-node, local) Slurm cluster, docs/scaling.md:
#  1. starts the cluster (scripts/slurm_local.sh, in its own folder and port), stopped on exit;
#  2. runs the sample pipeline sharded 3 ways through Slurm (shard --submit --wait) and checks every
#     product equals the one-machine `run` byte for byte (report.json: but for timings, paths and
#     its shard section);
#  3. a second sharded run in which task 1 of the passes phase fails (PCDP_SHARD_FAIL_TASK=1, read by
#     the job script): --wait exits non-zero, the reduce is cancelled by its failed dependency and
#     writes nothing; the reduce run by hand refuses, naming that task; rerunning only that task and
#     the reduce through sbatch completes, and the products equal the one-machine run.
# Needs a built build/tools/pcd_pipeline (PCDP_BIN to use another), python3, and the Debian Slurm
# packages (slurm_local.sh installs them when missing).
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT="$PWD"
BIN="$(readlink -f "${PCDP_BIN:-build/tools/pcd_pipeline}")"
[ -x "$BIN" ] || { echo "slurm_ci: no $BIN (build pcd_pipeline first)" >&2; exit 1; }
export SLURM_LOCAL_DIR="${SLURM_LOCAL_DIR:-/tmp/pcdp-slurm-ci.$$}"
export SLURM_LOCAL_PORT="${SLURM_LOCAL_PORT:-6837}"
WORK="$(mktemp -d /tmp/pcdp-slurm-ci-work.XXXXXX)"
chmod 755 "$WORK"
cleanup() {
  local rc=$?
  "$ROOT/scripts/slurm_local.sh" stop >/dev/null 2>&1 || true
  rm -rf "$SLURM_LOCAL_DIR" "$WORK"
  exit $rc
}
trap cleanup EXIT
trap 'exit 130' INT TERM
fail() { echo "slurm_ci: FAIL: $*" >&2; exit 1; }

scripts/slurm_local.sh start >/dev/null
eval "$(scripts/slurm_local.sh env)"
# shellcheck source=scripts/slurm_lib.sh disable=SC1091
. scripts/slurm_lib.sh

PIPELINE="$ROOT/pipelines/nodding_terrain.yaml"
"$BIN" run "$PIPELINE" -q -j 2 --output-dir "$WORK/ref"

same_as_ref() {  # same_as_ref OUT: every product of the one-machine run, equal
  local out="$1" f n
  for f in "$WORK/ref"/*; do
    n="$(basename "$f")"
    [ -e "$out/$n" ] || fail "$out/$n missing"
    if [ "$n" = report.json ]; then
      python3 - "$f" "$out/$n" <<'PY' || fail "$out/report.json differs from the one-machine run's"
import json, sys
DROP = {"seconds", "started_at", "phases", "threads", "output_dir", "outputs", "timings", "cpu_seconds", "shard"}
def strip(x):
    if isinstance(x, dict):
        return {k: strip(v) for k, v in x.items() if k not in DROP and not k.endswith("_seconds")}
    if isinstance(x, list):
        return [strip(v) for v in x]
    return x
a, b = (json.load(open(p)) for p in sys.argv[1:3])
sys.exit(0 if strip(a) == strip(b) and "shard" in b else 1)
PY
    else
      cmp -s "$f" "$out/$n" || fail "$out/$n differs from the one-machine run's"
    fi
  done
  [ "$(find "$out" -mindepth 1 -maxdepth 1 | wc -l)" = "$(find "$WORK/ref" -mindepth 1 -maxdepth 1 | wc -l)" ] || fail "$out holds other files than the one-machine run"
}

echo "slurm_ci: 3 shards through Slurm"
t0=$SECONDS
"$BIN" shard "$PIPELINE" --shards 3 --work-dir "$WORK/w1" --output-dir "$WORK/out1" --submit --wait --wait-timeout 300
same_as_ref "$WORK/out1"
echo "slurm_ci: products equal the one-machine run ($((SECONDS - t0)) s)"

echo "slurm_ci: 3 shards, task 1 of phase passes made to fail"
set +e
PCDP_SHARD_FAIL_TASK=1 "$BIN" shard "$PIPELINE" --shards 3 --work-dir "$WORK/w2" --output-dir "$WORK/out2" --submit --wait \
  --wait-timeout 300 >"$WORK/submit2.txt"
rc=$?
set -e
cat "$WORK/submit2.txt"
[ $rc -ne 0 ] || fail "--wait exited 0 although a task failed"
grep -Eq '_1 FAILED' "$WORK/submit2.txt" || fail "task 1 of phase passes is not reported FAILED"
grep -Eq ' CANCELLED reason=DependencyNeverSatisfied' "$WORK/submit2.txt" || fail "the reduce was not cancelled by its dependency"
[ ! -e "$WORK/out2" ] || fail "the failed run wrote outputs"
set +e
"$BIN" shard-task "$WORK/w2" reduce 2>"$WORK/reduce2.txt"
rc=$?
set -e
[ $rc -eq 3 ] || fail "the reduce over a missing partial exited $rc, not 3"
grep -q "shard-task $WORK/w2 passes 1" "$WORK/reduce2.txt" || fail "the reduce did not name task 1: $(cat "$WORK/reduce2.txt")"
if grep -q "passes 0\|passes 2" "$WORK/reduce2.txt"; then fail "the reduce names tasks that completed"; fi
echo "slurm_ci: the reduce refuses, naming task 1; rerunning it through sbatch"
rerun="$(sbatch --parsable --array=1 "$WORK/w2/jobs/passes.sh")"
reduce="$(sbatch --parsable --dependency="afterok:${rerun%%;*}" --kill-on-invalid-dep=yes "$WORK/w2/jobs/reduce.sh")"
slurm_wait_jobs -t 300 "${rerun%%;*}" "${reduce%%;*}" || fail "the rerun did not complete"
same_as_ref "$WORK/out2"
echo "slurm_ci: OK (rerun of one task completed the run; products equal the one-machine run)"
