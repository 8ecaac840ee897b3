#!/usr/bin/env bash
# A real scheduler: a one-node Slurm cluster on this host (munged,
# slurmctld, slurmd, all in a temporary folder, on free ports) runs the
# farm example's scripts on a small batch job: a 4-task array (2 turntable
# frames × 2 tiles), then the merge as a job depending on it
# (afterok). The merged frames and the animated PNG must be the bytes of
# a single-process render. The daemons are stopped on exit.
#
# slurm-wlm and munge are installed with apt-get when missing. Where they
# cannot be (not root, no apt, no network) it prints SKIPPED and exits 0.
#
#   tests/slurm/run.sh [path/to/lapidary]   (default target/release/lapidary)
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
lapidary=$(realpath "${1:-$root/target/release/lapidary}")
started=$SECONDS

skip() {
    echo "SKIPPED: the Slurm test did not run: $*" >&2
    echo "SKIPPED: the Slurm test did not run: $*"
    exit 0
}

missing=()
command -v slurmctld >/dev/null || missing+=(slurm-wlm)
command -v munged >/dev/null || missing+=(munge)
if ((${#missing[@]})); then
    [[ $(id -u) == 0 ]] || skip "${missing[*]} missing and not root to install them"
    command -v apt-get >/dev/null || skip "${missing[*]} missing and no apt-get"
    echo "slurm test: installing ${missing[*]}" >&2
    export DEBIAN_FRONTEND=noninteractive
    if ! apt-get install -y -q --no-install-recommends "${missing[@]}" >/tmp/lapidary-slurm-apt.log 2>&1; then
        apt-get update -q >>/tmp/lapidary-slurm-apt.log 2>&1 &&
            apt-get install -y -q --no-install-recommends "${missing[@]}" >>/tmp/lapidary-slurm-apt.log 2>&1 ||
            skip "apt-get could not install ${missing[*]} (see /tmp/lapidary-slurm-apt.log)"
    fi
fi
[[ $(id -u) == 0 ]] || skip "slurmd must run as root here (SlurmUser=root)"

work=$(mktemp -d /tmp/lapidary-slurm.XXXXXX)
daemons=()
stop_daemons() {
    local pid
    for pid in "${daemons[@]}"; do
        kill "$pid" 2>/dev/null || true
    done
    for pid in "${daemons[@]}"; do
        for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
        kill -9 "$pid" 2>/dev/null || true
    done
}
show_logs() {
    for log in "$work"/*.log "$work"/job/*.log; do
        [[ -f $log ]] && { echo "--- $log"; tail -n 20 "$log"; }
    done >&2
}
trap 'status=$?; stop_daemons; ((status == 0)) || show_logs; rm -rf "$work"' EXIT
fail() {
    echo "FAILED: the Slurm test: $*" >&2
    exit 1
}

# Two free TCP ports (nothing listening) for slurmctld and slurmd, so
# that this cluster never meets another one on the host.
free_port() {
    local port
    while :; do
        port=$((20000 + RANDOM % 20000))
        (exec 3<>"/dev/tcp/127.0.0.1/$port") 2>/dev/null || { echo "$port"; return; }
    done
}
ctld_port=$(free_port)
slurmd_port=$(free_port)
[[ $ctld_port != "$slurmd_port" ]] || slurmd_port=$((ctld_port + 1))

host=$(hostname -s)
# A fresh munge key, and munged on its own socket.
dd if=/dev/urandom of="$work/munge.key" bs=1024 count=1 status=none
chmod 400 "$work/munge.key"
munged --force --key-file="$work/munge.key" --socket="$work/munge.socket" \
    --pid-file="$work/munged.pid" --log-file="$work/munged.log" \
    --seed-file="$work/munge.seed" || fail "munged did not start"
daemons+=("$(cat "$work/munged.pid")")

node=$(slurmd -C | head -n 1)   # NodeName=… CPUs=… RealMemory=… as this host has
mkdir -p "$work/state" "$work/spool" "$work/job"
cat >"$work/slurm.conf" <<CONF
ClusterName=lapidarytest
SlurmctldHost=$host
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$work/munge.socket
StateSaveLocation=$work/state
SlurmdSpoolDir=$work/spool
SlurmctldPidFile=$work/slurmctld.pid
SlurmdPidFile=$work/slurmd.pid
SlurmctldLogFile=$work/slurmctld.log
SlurmdLogFile=$work/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
MpiDefault=none
ReturnToService=2
$node State=UNKNOWN
PartitionName=farm Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
cat >"$work/cgroup.conf" <<CONF
CgroupPlugin=autodetect
IgnoreSystemd=yes
CONF
export SLURM_CONF=$work/slurm.conf
slurmctld -f "$SLURM_CONF" || fail "slurmctld did not start"
for _ in $(seq 50); do [[ -s $work/slurmctld.pid ]] && break; sleep 0.1; done
daemons+=("$(cat "$work/slurmctld.pid")")
slurmd -f "$SLURM_CONF" || fail "slurmd did not start"
for _ in $(seq 50); do [[ -s $work/slurmd.pid ]] && break; sleep 0.1; done
daemons+=("$(cat "$work/slurmd.pid")")

for _ in $(seq 120); do
    state=$(sinfo -h -N -o %T 2>/dev/null | head -n 1 || true)
    [[ $state == idle ]] && break
    sleep 0.5
done
[[ $state == idle ]] || fail "the node is '$state', not idle, after 60 s"

# The job: goldstone on a 2-frame turntable, each frame in 2 tiles.
cd "$work/job"
cat >job.ron <<'JOB'
Job(
    output: "out",
    recipes: ["goldstone"],
    settings: [Settings(width: 32, height: 32, spp: 4)],
    turntable: Some(Turntable(frames: 2, turn: Stone)),
    tiles: 2,
)
JOB
export LAPIDARY=$lapidary LAPIDARY_CACHE=off
tasks=$("$lapidary" batch job.ron 2>/dev/null | wc -l)
[[ $tasks == 4 ]] || fail "the job has $tasks tasks, expected 4"
# The three commands of the README, as a farm user types them.
jid=$(sbatch --parsable --array=0-$((tasks - 1)) "$root/examples/farm/slurm-array.sh" job.ron)
sbatch --parsable --wait --dependency=afterok:"$jid" "$root/examples/farm/slurm-merge.sh" job.ron >/dev/null ||
    fail "the merge job failed"

"$lapidary" render goldstone --size 32 --spp 4 --frames 2 -o single.png -q
for file in goldstone-studio-0000.png goldstone-studio-0001.png goldstone-studio.png; do
    cmp "out/$file" "single${file#goldstone-studio}" || fail "out/$file differs from the single-process render"
done
echo "slurm test: a 4-task array and its merge gave the single-process bytes in $((SECONDS - started)) s"
