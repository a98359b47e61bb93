#!/bin/bash
# The farm contract on a real Slurm (docs/farm.md): starts a single-host cluster (munged,
# slurmctld, slurmd on 127.0.0.1, all in a temporary folder, stopped on exit), bakes a shared
# level with scripts/slurm-bake as a 4-shard array job + merge + bake, kills one shard's
# lightlink mid-run, and checks that Slurm ran that shard again, that the merged artifact is
# byte-identical to one machine's `lightlink precompute`, and that the bake reused it.
# Exit 77 (skipped, with the reason) without slurm-wlm/munge, without root (slurmd launches
# the jobs), or without the shared scenes.
# usage: slurm_farm_test.sh LIGHTLINK SOURCE_DIR SHARED_SCENES_DIR
set -euo pipefail
lightlink=$1 source_dir=$2 scenes=$3

skip() { echo "SKIP: $*"; exit 77; }
for b in munged mungekey slurmctld slurmd sbatch scontrol squeue sinfo; do
  command -v "$b" >/dev/null || [ -x "/usr/sbin/$b" ] ||
    skip "$b not found: install slurm-wlm and munge (scripts/packages.txt)"
done
export PATH="$PATH:/usr/sbin"
[ "$(id -u)" = 0 ] || skip "a single-host Slurm needs root here (slurmd launches the jobs); CI runs as root"
# The largest shared level: ~4 s to precompute at medium on 2 cores, a few shards' worth.
scene="$scenes/sauerbraten_zdm2_level_gltf/zdm2.glb"
[ -f "$scene" ] || skip "shared scene $scene is absent"

tmp=$(mktemp -d /tmp/lightlink-slurm.XXXXXX)
chmod 755 "$tmp"  # munged checks that every directory above its socket is searchable
ok=0
stop_daemons() {
  local p pid
  for p in slurmd slurmctld munged; do
    [ -f "$tmp/$p.pid" ] || continue
    pid=$(cat "$tmp/$p.pid")
    kill "$pid" 2>/dev/null || continue
    for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    kill -9 "$pid" 2>/dev/null || true
  done
}
cleanup() {
  # Jobs still running (a failed check) first: their slurmstepd would outlive slurmd.
  if [ -n "${SLURM_CONF:-}" ] && [ -n "$(squeue -h -o %A 2>/dev/null)" ]; then
    scancel -u "$(id -un)" 2>/dev/null || true
    for _ in $(seq 50); do [ -z "$(squeue -h -o %A 2>/dev/null)" ] && break; sleep 0.1; done
  fi
  stop_daemons
  if [ "$ok" != 1 ]; then
    for f in "$tmp"/log/*.log "$tmp"/out/farm/logs/*.log; do
      [ -f "$f" ] && { echo "---- $f"; tail -n 30 "$f"; }
    done
  fi
  rm -rf "$tmp"
}
trap cleanup EXIT
trap 'echo "FAIL: command at line $LINENO failed"' ERR

# munge: a fresh key and socket in $tmp.
mkdir -p "$tmp/munge" "$tmp/log" "$tmp/state" "$tmp/spool"
chmod 755 "$tmp/munge"
mungekey --create --keyfile="$tmp/munge/munge.key"
munged --key-file="$tmp/munge/munge.key" --socket="$tmp/munge/munge.sock" --pid-file="$tmp/munged.pid" \
  --log-file="$tmp/log/munged.log" --seed-file="$tmp/munge/munged.seed"

# slurm: controller and node on this host, on two free ports.
read -r ctld_port slurmd_port < <(python3 -c '
import socket
s = [socket.socket() for _ in range(2)]
for x in s: x.bind(("127.0.0.1", 0))
print(*[x.getsockname()[1] for x in s])')
host=$(hostname -s)
cat >"$tmp/slurm.conf" <<EOF
ClusterName=lightlinktest
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$tmp/munge/munge.sock
CredType=cred/munge
StateSaveLocation=$tmp/state
SlurmdSpoolDir=$tmp/spool
SlurmctldPidFile=$tmp/slurmctld.pid
SlurmdPidFile=$tmp/slurmd.pid
SlurmctldLogFile=$tmp/log/slurmctld.log
SlurmdLogFile=$tmp/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SwitchType=switch/none
MpiDefault=none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
JobAcctGatherType=jobacct_gather/none
ReturnToService=2
JobRequeue=1
MinJobAge=600
SchedulerParameters=sched_interval=1
NodeName=$host NodeAddr=127.0.0.1 CPUs=$(nproc) State=UNKNOWN
PartitionName=debug Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
export SLURM_CONF="$tmp/slurm.conf"
slurmctld -i
slurmd
for _ in $(seq 100); do
  sinfo -h -o %t 2>/dev/null | grep -q idle && break
  sleep 0.2
done
sinfo -h -o %t | grep -q idle || { echo "FAIL: the single-host Slurm did not come up"; exit 1; }
echo "slurm up: $(sinfo -h -o '%P %D %t %c')"

# One machine's artifact, the reference.
options=(--preset medium)
start=$(date +%s.%N)
"$lightlink" precompute "$scene" -o "$tmp/single.llk" -q "${options[@]}" 2>/dev/null
echo "single-machine precompute: $(python3 -c "print(f'{$(date +%s.%N) - $start:.1f}')") s"

# The farm: 4 shards, merge, bake; slurm-bake --wait returns when the bake job is done.
"$source_dir/scripts/slurm-bake" "$scene" -o "$tmp/out" --shards 4 --lightlink "$lightlink" --wait \
  -- "${options[@]}" >"$tmp/slurm-bake.out" 2>&1 &
submitter=$!
work="$tmp/out/farm"
for _ in $(seq 300); do [ -f "$work/jobs.env" ] && break; sleep 0.1; done
[ -f "$work/jobs.env" ] || { echo "FAIL: slurm-bake submitted nothing"; cat "$tmp/slurm-bake.out"; exit 1; }
source "$work/jobs.env"

# Kill shard 1's lightlink as soon as it runs (SIGKILL, as the OOM killer or a lost node would).
killed=0
for _ in $(seq 3000); do
  if [ -f "$work/run/shard_1.pid" ]; then
    pid=$(cat "$work/run/shard_1.pid")
    if [ -n "$pid" ] && kill -9 "$pid" 2>/dev/null; then killed=1; break; fi
  fi
  sleep 0.02
done
[ "$killed" = 1 ] || { echo "FAIL: shard 1 was never seen running, so it could not be killed"; exit 1; }
echo "killed shard 1's lightlink (pid $pid) mid-run"

# Until the bake job is done. Slurm holds a requeued job for ~2 minutes (its requeue begin
# time); a real cluster waits, the test releases it at once.
deadline=$((SECONDS + 240))
while [ -n "$(squeue -h -j "$BAKE_JOB" -o %i 2>/dev/null)" ]; do
  [ $SECONDS -lt $deadline ] || { echo "FAIL: the jobs did not finish in 240 s"; squeue; exit 1; }
  squeue -h -r -j "$PRECOMPUTE_JOB" -t PD -o '%i %r' 2>/dev/null | while read -r id reason; do
    if [ "$reason" = BeginTime ]; then scontrol update JobId="$id" StartTime=now; fi
  done
  sleep 0.5
done

wait "$submitter" || { echo "FAIL: slurm-bake --wait exited $?"; cat "$tmp/slurm-bake.out"; exit 1; }
grep -q "last job $BAKE_JOB: COMPLETED" "$tmp/slurm-bake.out" || { echo "FAIL: slurm-bake --wait did not report the bake"; cat "$tmp/slurm-bake.out"; exit 1; }
state() { scontrol show job "$1" | sed -n 's/.*JobState=\([A-Z_]*\).*/\1/p' | head -n 1; }
for j in "${PRECOMPUTE_JOB}_0" "${PRECOMPUTE_JOB}_1" "${PRECOMPUTE_JOB}_2" "${PRECOMPUTE_JOB}_3" "$MERGE_JOB" "$BAKE_JOB"; do
  s=$(state "$j")
  [ "$s" = COMPLETED ] || { echo "FAIL: job $j ended $s"; exit 1; }
done
restarts=$(scontrol show job "${PRECOMPUTE_JOB}_1" | sed -n 's/.*Restarts=\([0-9]*\).*/\1/p')
[ "$restarts" = 1 ] || { echo "FAIL: shard 1 was restarted ${restarts:-?} times, expected 1"; exit 1; }
grep -q "attempt 2" "$work/logs/shard_1.log" || { echo "FAIL: shard 1's log shows no second attempt"; exit 1; }
echo "shard 1 requeued by Slurm and rerun: $(grep -c "^shard 1/4 attempt" "$work/logs/shard_1.log") attempts"

merged=$(ls "$work/cache/"*.llk)
cmp "$tmp/single.llk" "$merged" || { echo "FAIL: the merged artifact differs from the single-machine one"; exit 1; }
echo "merged artifact $(basename "$merged") is byte-identical to the single-machine one ($(stat -c %s "$merged") bytes)"
grep -q '"artifact": "reused' "$tmp/out/report.json" || { echo "FAIL: the bake step did not reuse the merged artifact"; exit 1; }
[ -f "$tmp/out/irradiance.exr" ] || { echo "FAIL: the bake step wrote no irradiance.exr"; exit 1; }
echo "bake step reused it and wrote its outputs"
ok=1
echo "PASS"
