#!/usr/bin/env bash
# The Slurm acceptance test of `tumble sweep` (ctest label `slurm`): a real single-node cluster on this
# machine (tests/slurm/local_cluster.sh: munged, slurmctld and slurmd on localhost ports, every file in a
# folder of its own), a 24-case sweep run as an array of 4 tasks, its merged table equal to the --local
# run's row for row (hashes bit for bit; the timing columns aside); then the same sweep with one task
# cancelled before it starts (a lost task), which the sweep must submit again and still finish. The daemons
# it started are stopped whatever happens. Needs root (Slurm runs as root here); exit 77 (skipped) without.
#
#   slurm_sweep_test.sh TUMBLE_BINARY
set -euo pipefail
tumble=$1
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
if [ "$(id -u)" -ne 0 ]; then
    echo "skipped: the single-node Slurm cluster runs its daemons as root"
    exit 77
fi
for program in munged slurmctld slurmd sbatch squeue; do
    command -v "$program" >/dev/null || { echo "missing $program: apt-get install slurm-wlm munge" >&2; exit 1; }
done

# a short path: the munge socket's must fit in 108 bytes
work=$(mktemp -d /tmp/tumble-slurm.XXXXXX)
chmod go+x "$work" # munged wants every folder above its socket open to all
cleanup() {
    bash "$here/local_cluster.sh" stop "$work/cluster" || true
    rm -rf "$work"
}
trap cleanup EXIT
cluster=$(bash "$here/local_cluster.sh" start "$work/cluster")
eval "$cluster"

cat >"$work/sweep24.toml" <<'TOML'
[sweep]
scenario = "rope"
frames = 30

[[axis]]
key = "chain.rope.stiffness"
values = [300.0, 600.0, 1200.0, 2400.0, 4800.0, 1e9]

[[axis]]
key = "chain.rope.damping"
range = [0.1, 0.4, 4]

[[metric]]
name = "end_x"
entity = "chain"
TOML

# the table without its three timing columns (physics_p50_ms, physics_p99_ms, physics_max_ms)
untimed() {
    cut -d, --complement -f 6-8 "$1"
}

"$tumble" sweep "$work/sweep24.toml" --local --out "$work/local" --quiet
# a folder with a space and a % in its path: one argument to sbatch, not a pattern
slurm="$work/slurm 100%"
time "$tumble" sweep "$work/sweep24.toml" --slurm --tasks 4 --out "$slurm"
[ "$(wc -l <"$slurm/results.csv")" -eq 25 ] || { echo "FAIL: not 24 rows" >&2; exit 1; }
diff <(untimed "$work/local/results.csv") <(untimed "$slurm/results.csv") ||
    { echo "FAIL: the Slurm table differs from the local one" >&2; exit 1; }
grep -q -- '--array=0-3 ' "$slurm/slurm/submit.txt" || { echo "FAIL: not an array of 4" >&2; exit 1; }
for task in 0 1 2 3; do
    ls "$slurm"/slurm/task_*_"$task".log >/dev/null || { echo "FAIL: no log of task $task" >&2; exit 1; }
done
echo "ok: 24 cases in 4 array tasks, the same table as --local"

# a lost task: one at a time, task 2 cancelled while it waits; the sweep submits it again
"$tumble" sweep "$work/sweep24.toml" --slurm --tasks 4 --max-parallel 1 --out "$work/lost" >"$work/lost.txt" &
sweep=$!
for _ in $(seq 1 200); do
    [ -s "$work/lost/slurm/job" ] && break
    sleep 0.05
done
scancel "$(cat "$work/lost/slurm/job")_2"
wait "$sweep"
cat "$work/lost.txt"
grep -q 'tasks 2 left cases undone; submitted them again' "$work/lost.txt" ||
    { echo "FAIL: the cancelled task was not submitted again" >&2; exit 1; }
diff <(untimed "$work/local/results.csv") <(untimed "$work/lost/results.csv") ||
    { echo "FAIL: the table after a lost task differs from the local one" >&2; exit 1; }
echo "ok: a cancelled task submitted again, the same table"
