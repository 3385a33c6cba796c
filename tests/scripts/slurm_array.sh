#!/usr/bin/env bash
# slurm_array.sh SOURCE_DIR PRODYGS TMP - scripts/slurm-array on a real single-node Slurm.
#
# Starts slurmctld and slurmd (Debian's slurm-wlm) with a slurm.conf generated in TMP (no munge:
# auth/none, own ports, own state and spool folders; nothing of the machine's /etc/slurm is
# used), makes two tiny clips with `prodygs synth`, runs them as a two-task array with
# `scripts/slurm-array submit` plus its summary job, checks both runs and the gathered summary,
# then submits again and checks that every stage is skipped (the resumable case). Exits 77
# (ctest SKIP) with the reason when Slurm is not installed or its daemons cannot start here.
set -euo pipefail
src=$(readlink -f "$1") prodygs=$(readlink -f "$2") tmp=$3
skip() { echo "slurm_array: SKIP: $*"; exit 77; }
for c in slurmctld slurmd sbatch squeue sinfo scontrol; do
  command -v "$c" >/dev/null 2>&1 || skip "$c not installed (apt-get install slurm-wlm)"
done
[ "$(id -u)" -eq 0 ] || skip "slurmd needs root to start jobs as their user; run as root"
rm -rf "$tmp" && mkdir -p "$tmp"/{state,spool,run}
tmp=$(readlink -f "$tmp")
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
  for p in "${pids[@]}"; do wait "$p" 2>/dev/null || true; done
}
trap cleanup EXIT

ports=$(/usr/bin/python3 -c 'import socket
s = [socket.socket() for _ in range(2)]
for x in s: x.bind(("127.0.0.1", 0))
print(" ".join(str(x.getsockname()[1]) for x in s))')
read -r ctld_port d_port <<<"$ports"
node=$(slurmd -C | awk 'NR==1')          # this machine as slurmd sees it: NodeName=... CPUs=... RealMemory=...
host=$(sed -n 's/^NodeName=\([^ ]*\).*/\1/p' <<<"$node")
cpus=$(sed -n 's/.* CPUs=\([0-9]*\).*/\1/p' <<<"$node")
export SLURM_CONF=$tmp/slurm.conf
cat >"$SLURM_CONF" <<EOF
ClusterName=prodygs-test
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$d_port
AuthType=auth/none
CredType=cred/none
SlurmUser=root
SlurmdUser=root
StateSaveLocation=$tmp/state
SlurmdSpoolDir=$tmp/spool
SlurmctldPidFile=$tmp/run/slurmctld.pid
SlurmdPidFile=$tmp/run/slurmd.pid
SlurmctldLogFile=$tmp/slurmctld.log
SlurmdLogFile=$tmp/slurmd.log
ProctrackType=proctrack/pgid
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
MpiDefault=none
ReturnToService=2
SchedulerParameters=sched_interval=1
MessageTimeout=20
$node NodeAddr=127.0.0.1 State=UNKNOWN
PartitionName=test Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
slurmctld -D -c -f "$SLURM_CONF" >"$tmp/slurmctld.out" 2>&1 &
pids+=($!)
slurmd -D -f "$SLURM_CONF" -N "$host" >"$tmp/slurmd.out" 2>&1 &
pids+=($!)
for i in $(seq 60); do
  state=$(sinfo -h -N -o %T 2>/dev/null | head -n1 || true)
  case $state in idle*|mix*|alloc*) break ;; esac
  for p in "${pids[@]}"; do
    kill -0 "$p" 2>/dev/null || { tail -n 5 "$tmp"/*.log "$tmp"/*.out 2>/dev/null; skip "a Slurm daemon exited at start (logs above)"; }
  done
  sleep 0.5
done
case $state in idle*|mix*|alloc*) ;; *) tail -n 5 "$tmp"/*.log 2>/dev/null; skip "the node did not come up (state '$state')" ;; esac
echo "slurm_array: slurmctld + slurmd up on $host ($cpus CPUs), node $state"

# two tiny clips: the sample scene's centre camera at two seeds
for s in 1 2; do
  "$prodygs" synth "$tmp/scene$s" --cams 1 --frames 6 --size 96x72 --seed "$s" --video --threads 1 >/dev/null 2>&1
done
printf '# two clips\n%s\n%s clip2\n' "$tmp/scene1/cam00.mp4" "$tmp/scene2/cam00.mp4" >"$tmp/clips.txt"
out=$tmp/out
fast=(--iters 30 --proxies 2)

wait_jobs() { # every job of this cluster ended, or 150 s
  for i in $(seq 300); do
    [ -z "$(squeue -h -o %i 2>/dev/null)" ] && return 0
    sleep 0.5
  done
  squeue; echo "slurm_array: jobs still queued after 150 s"; return 1
}

t0=$(date +%s)
PRODYGS=$prodygs "$src/scripts/slurm-array" submit "$tmp/clips.txt" "$out" --cpus-per-task=1 -- "${fast[@]}" | tee "$tmp/submit1.txt"
wait_jobs
t1=$(date +%s)
echo "slurm_array: the array and its summary ran in $((t1 - t0)) s"
cat "$out/summary.md"
for name in cam00 clip2; do
  grep -q "^| $name | done |" "$out/summary.md" || { echo "slurm_array: $name is not done"; tail -n 20 "$out/$name.log" "$out"/slurm-*.log; exit 1; }
  # --threads came from the allocation (1 CPU per task)
  grep -q -- "--threads 1 --iters 30 --proxies 2" "$out/$name/report.md" || { echo "slurm_array: $name: --threads not from SLURM_CPUS_PER_TASK"; head -n 5 "$out/$name/report.md"; exit 1; }
done
grep -q "^2 of 2 clips done" "$out/summary.md"

# submitted again, by hand this time (plain sbatch from the checkout, prodygs found through
# SLURM_SUBMIT_DIR): every task finds its run finished and skips each stage (resumable)
mkdir -p "$tmp/checkout-root" && ln -sfn "$(dirname "$prodygs")" "$tmp/checkout-root/build"
(cd "$tmp/checkout-root" && env -u PRODYGS sbatch --parsable --array=1-2 --cpus-per-task=1 --output="$out/slurm-again-%A_%a.log" \
   "$src/scripts/slurm-array" "$tmp/clips.txt" "$out" "${fast[@]}") >"$tmp/submit2.txt"
wait_jobs
"$src/scripts/gather-runs" "$out" --list "$tmp/clips.txt" >"$out/summary.md"
for name in cam00 clip2; do
  n=$(grep -c "already done with these settings and inputs, skipping" "$out/$name.log" || true)
  [ "$n" -ge 3 ] || { echo "slurm_array: $name: the second submission did not skip the finished stages"; tail -n 20 "$out/$name.log"; exit 1; }
done
grep -q "^2 of 2 clips done" "$out/summary.md"
echo "slurm_array: ok (two-task array + summary job in $((t1 - t0)) s; a plain sbatch resubmission skipped every finished stage)"
