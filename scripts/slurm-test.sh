#!/usr/bin/env bash
# Runs the Slurm array job of docs/cluster.md for real on this machine:
#   1. installs Debian's slurm-wlm and munge (apt-get) if missing;
#   2. starts a private munged, slurmctld and slurmd on localhost (their own
#      config, state, sockets and ports under a temporary folder);
#   3. submits the documented job script, taken from docs/cluster.md, as a
#      3-task array on a tiny Workbench config;
#   4. kills task 1 (SIGKILL to its grasp-gen) once it has finished a
#      sequence and before it has finished all, requeues it (scontrol
#      requeue) and lets Slurm run it again;
#   5. merges the shards, verifies the merged dataset against the config and
#      compares it with a one-machine render of the same config: the same
#      files byte for byte, except the wall-clock render.cost in each
#      sequence.json.
# Needs root (packages, daemons). Stops only the daemons it started.
# Usage: scripts/slurm-test.sh        (KEEP=1 keeps the temporary folder)
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)
START=$SECONDS
if [ "$(id -u)" != 0 ]; then
  echo "slurm-test: needs root (apt-get install, Slurm and munge daemons)" >&2
  exit 2
fi

scripts/setup.sh
export PATH="$ROOT/target/release:$PATH"

echo "== packages"
if ! command -v slurmctld >/dev/null || ! command -v munged >/dev/null; then
  apt-get -o DPkg::Lock::Timeout=600 update -qq
  DEBIAN_FRONTEND=noninteractive apt-get -o DPkg::Lock::Timeout=600 install -y -qq --no-install-recommends \
    slurm-wlm munge >/dev/null
fi
INSTALLED=$SECONDS

WORK=$(mktemp -d "${TMPDIR:-/tmp}/grasp-slurm.XXXXXX")
chmod 755 "$WORK"
S="$WORK/slurm"
mkdir -p "$S/munge" "$S/state" "$S/spool" "$S/log"
JOB=
stop_daemons() {
  # A failure mid-way: cancel the job first, so no job step outlives slurmd.
  if [ -n "$JOB" ] && [ -n "$(squeue -h -j "$JOB" 2>/dev/null)" ]; then
    scancel "$JOB" || true
    for _ in $(seq 60); do
      [ -z "$(squeue -h -j "$JOB" 2>/dev/null)" ] && break
      sleep 1
    done
  fi
  # Only what this script started, by the pids they wrote.
  for f in "$S/slurmd.pid" "$S/slurmctld.pid" "$S/munge/munged.pid"; do
    [ -s "$f" ] && kill "$(cat "$f")" 2>/dev/null || true
  done
  if [ "${KEEP:-0}" = 1 ]; then
    echo "kept $WORK"
  else
    sleep 1
    rm -rf "$WORK"
  fi
}
trap stop_daemons EXIT

echo "== munge and Slurm on localhost ($WORK)"
cp /etc/munge/munge.key "$S/munge/munge.key" 2>/dev/null ||
  dd if=/dev/urandom of="$S/munge/munge.key" bs=1024 count=1 status=none
chown -R munge:munge "$S/munge"
chmod 711 "$S/munge"
chmod 400 "$S/munge/munge.key"
runuser -u munge -- /usr/sbin/munged --socket="$S/munge/munge.socket" \
  --key-file="$S/munge/munge.key" --pid-file="$S/munge/munged.pid" \
  --log-file="$S/munge/munged.log" --seed-file="$S/munge/munged.seed"

HOST=$(hostname -s)
# Two free TCP ports, so this Slurm never meets another one on the machine.
read -r CTLD_PORT SLURMD_PORT < <(python3 -c '
import socket
socks = [socket.socket() for _ in range(2)]
for s in socks:
    s.bind(("127.0.0.1", 0))
print(*(s.getsockname()[1] for s in socks))')
MEM=$(awk '/MemTotal/ {print int($2 / 1024 * 0.8)}' /proc/meminfo)
cat >"$S/slurm.conf" <<EOF
ClusterName=grasptest
SlurmctldHost=$HOST(127.0.0.1)
SlurmctldPort=$CTLD_PORT
SlurmdPort=$SLURMD_PORT
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$S/munge/munge.socket
SlurmUser=root
SlurmdUser=root
StateSaveLocation=$S/state
SlurmdSpoolDir=$S/spool
SlurmctldPidFile=$S/slurmctld.pid
SlurmdPidFile=$S/slurmd.pid
SlurmctldLogFile=$S/log/slurmctld.log
SlurmdLogFile=$S/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SchedulerType=sched/backfill
MpiDefault=none
ReturnToService=2
JobRequeue=1
MinJobAge=3600
NodeName=$HOST NodeAddr=127.0.0.1 CPUs=$(nproc) RealMemory=$MEM State=UNKNOWN
PartitionName=test Nodes=$HOST Default=YES MaxTime=INFINITE State=UP
EOF
export SLURM_CONF="$S/slurm.conf"
slurmctld
slurmd
for _ in $(seq 60); do
  sinfo -h -o %T 2>/dev/null | grep -q idle && break
  sleep 1
done
sinfo -h -o %T | grep -q idle || { tail "$S/log/"*; echo "Slurm did not come up" >&2; exit 1; }

echo "== the documented job"
cd "$WORK"
cat >tiny.toml <<'EOF'
[dataset]
sequences_per_pair = 3
conditions = ["default"]
objects = ["025_mug"]

[plan.camera]
resolution = [48, 48]

[plan.trajectory]
fps = 30.0

[render]
engine = "workbench"
samples = 1
EOF
# The script block under "## Slurm array job" in docs/cluster.md, verbatim.
awk '/^## Slurm array job/ {s = 1; next}
     s == 1 && /^```sh/ {s = 2; next}
     s == 2 && /^```/ {exit}
     s == 2 {print}' "$ROOT/docs/cluster.md" >render.sbatch
grep -q 'grasp-gen render' render.sbatch || { echo "no job script in docs/cluster.md" >&2; exit 1; }
mkdir -p logs
# Sized for this machine on the command line; the script itself is unchanged.
JOB=$(CONFIG="$WORK/tiny.toml" WORKERS=1 sbatch --parsable --array=0-2 \
  --cpus-per-task=1 --mem=1G --time=30:00 --output="$WORK/logs/render-%A_%a.out" \
  render.sbatch)
echo "submitted array job $JOB"

state() { scontrol show job "${JOB}_$1" | grep -o 'JobState=[A-Z_]*' | cut -d= -f2; }
finished_in() { [ -f "shards/$1/manifest.jsonl" ] && wc -l <"shards/$1/manifest.jsonl" || echo 0; }
# Shard 1's sequences: every third of the 12 in key order.
TOTAL1=4
LOCK="shards/1/.grasp-gen/locks/shard-1-of-3.lock"
PID=
for i in $(seq 3000); do
  if [ -f "$LOCK" ] && [ "$(finished_in 1)" -ge 1 ]; then
    PID=$(grep -o '"pid": [0-9]*' "$LOCK" | grep -o '[0-9]*$') && break
  fi
  [ $((i % 50)) = 0 ] && echo "  waiting for task 1 to finish a sequence ($(state 1))"
  sleep 0.1
done
[ -n "$PID" ] || { echo "task 1 never finished a sequence" >&2; cat logs/* >&2; exit 1; }
# Kill its grasp-gen (the pid its lock names) with SIGKILL, as the OOM killer
# or a crashing node would: no clean-up at all. The batch script then fails.
kill -KILL "$PID"
done1=$(finished_in 1)
if [ "$done1" -ge "$TOTAL1" ]; then
  echo "task 1 finished before it could be killed" >&2
  exit 1
fi
echo "killed task 1's grasp-gen (pid $PID) mid-render: $done1 of $TOTAL1 sequences finished"
for _ in $(seq 300); do
  case "$(state 1)" in FAILED | COMPLETED | CANCELLED) break ;; esac
  sleep 0.1
done
echo "task 1: $(state 1); requeueing it"
scontrol requeue "${JOB}_1"
# Slurm holds a requeued job for two minutes (BeginTime); release it now.
for _ in $(seq 100); do
  [ "$(state 1)" = PENDING ] && break
  sleep 0.1
done
scontrol update JobId="${JOB}_1" StartTime=now

for _ in $(seq 1800); do
  [ -z "$(squeue -h -j "$JOB")" ] && break
  sleep 1
done
[ -z "$(squeue -h -j "$JOB")" ] || { echo "the array job did not finish" >&2; exit 1; }
for k in 0 1 2; do
  info=$(scontrol show job "${JOB}_$k")
  echo "task $k: $(echo "$info" | grep -oE '(JobState|Restarts|ExitCode)=[^ ]*' | tr '\n' ' ')"
  echo "$info" | grep -q 'JobState=COMPLETED' || { cat logs/*; exit 1; }
  echo "$info" | grep -q 'ExitCode=0:0' || { cat logs/*; exit 1; }
done
scontrol show job "${JOB}_1" | grep -q 'Restarts=1' || { echo "task 1 was not requeued" >&2; exit 1; }
LOG1=$(ls logs/render-*_1.out)
[ "$(grep -c 'shard 1/3:' "$LOG1")" = 1 ] || { cat "$LOG1"; echo "task 1's first run was not killed" >&2; exit 1; }
# The second run must find some sequences done and render the others.
grep -qE "shard 1/3: $TOTAL1 sequences, [1-9][0-9]* already done, [1-9][0-9]* rendered" "$LOG1" ||
  { cat "$LOG1"; echo "task 1 was not killed mid-render, or did not resume" >&2; exit 1; }
echo "--- task 1's log (both runs)"
cat "$LOG1"
echo "---"

echo "== merge, verify, compare with a one-machine render"
grasp-gen dataset merge data shards/0 shards/1 shards/2
grasp-gen dataset verify data --config tiny.toml --decode
grasp-gen render --config tiny.toml --out whole --no-progress
python3 - data whole <<'EOF'
import json, pathlib, sys

def tree(root):
    root = pathlib.Path(root)
    out = {}
    for p in sorted(root.rglob("*")):
        rel = p.relative_to(root)
        if p.is_dir() or any(part.startswith(".") for part in rel.parts):
            continue
        data = p.read_bytes()
        if p.name == "sequence.json":
            record = json.loads(data)
            record["render"].pop("cost")  # wall-clock seconds
            data = json.dumps(record, sort_keys=True).encode()
        out[str(rel)] = data

    return out

a, b = tree(sys.argv[1]), tree(sys.argv[2])
assert a.keys() == b.keys(), sorted(set(a) ^ set(b))
differ = [k for k in a if a[k] != b[k]]
assert not differ, differ
frames = sum(k.endswith(".png") for k in a)
print(f"merged shards == one-machine render: {len(a)} files ({frames} frames) identical")
EOF
echo "== slurm-test passed in $((SECONDS - START)) s (packages $((INSTALLED - START)) s)"
