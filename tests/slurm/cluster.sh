#!/usr/bin/env bash
# A one-node Slurm cluster on localhost for the tests, private to DIR:
#   cluster.sh start DIR   munged (own key and socket), slurmctld, slurmd on free
#                          ports; waits until the node is idle; prints the
#                          environment the clients need (SLURM_CONF=...).
#   cluster.sh stop DIR    stops the three daemons (by their pid files).
# Needs root (slurmd runs the jobs as their user) and Debian's slurmctld,
# slurmd and munge. No cgroups: proctrack/linuxproc, task/none.
set -euo pipefail
cmd=${1:?start|stop}
dir=${2:?DIR}

stop() {
  for d in slurmd slurmctld munged; do
    if [ -f "$dir/$d.pid" ]; then
      pid=$(cat "$dir/$d.pid" 2>/dev/null || true)
      if [ -n "$pid" ] && kill -0 "$pid" 2>/dev/null; then
        kill "$pid" 2>/dev/null || true
        for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
        kill -9 "$pid" 2>/dev/null || true
      fi
      rm -f "$dir/$d.pid"
    fi
  done
}

if [ "$cmd" = stop ]; then
  stop
  exit 0
fi

for b in munged mungekey slurmctld slurmd sinfo; do
  command -v "$b" >/dev/null || { echo "cluster.sh: $b not found (apt-get install slurmctld slurmd munge)" >&2; exit 3; }
done
[ "$(id -u)" = 0 ] || { echo "cluster.sh: needs root" >&2; exit 3; }

mkdir -p "$dir"
chmod 0700 "$dir"
mkdir -p "$dir/munge" "$dir/state" "$dir/spool"
chmod 0700 "$dir/munge"

# A free TCP port on 127.0.0.1 (bind to port 0 and read what was given).
free_port() {
  python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}

mungekey --create --keyfile="$dir/munge/munge.key" --force 2>/dev/null ||
  dd if=/dev/urandom of="$dir/munge/munge.key" bs=1024 count=1 2>/dev/null
chmod 0400 "$dir/munge/munge.key"
munged --force --key-file="$dir/munge/munge.key" --socket="$dir/munge/munge.socket" \
  --pid-file="$dir/munged.pid" --log-file="$dir/munge/munged.log" \
  --seed-file="$dir/munge/munged.seed" 2>"$dir/munged.err" || { cat "$dir/munged.err" >&2; exit 1; }

host=$(hostname -s)
cpus=$(nproc)
ctld_port=$(free_port)
slurmd_port=$(free_port)
while [ "$slurmd_port" = "$ctld_port" ]; do slurmd_port=$(free_port); done
cat > "$dir/slurm.conf" <<CONF
ClusterName=locforge-test
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$dir/munge/munge.socket
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/slurmctld.log
SlurmdLogFile=$dir/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MpiDefault=none
SwitchType=switch/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SlurmdParameters=config_overrides
ReturnToService=2
MinJobAge=3600
KillWait=5
InactiveLimit=0
# Memory is not enforced here (no cgroups) and config_overrides makes slurmd
# take this figure as is: large enough that locforge's built-in per-stage
# requests (up to 64G) are submitted unchanged.
NodeName=$host NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=131072 State=UNKNOWN
PartitionName=test Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF="$dir/slurm.conf"
slurmctld -f "$dir/slurm.conf" -i 2>"$dir/slurmctld.err" || { cat "$dir/slurmctld.err" "$dir/slurmctld.log" >&2; stop; exit 1; }
slurmd -f "$dir/slurm.conf" 2>"$dir/slurmd.err" || { cat "$dir/slurmd.err" "$dir/slurmd.log" >&2; stop; exit 1; }
for _ in $(seq 300); do
  if sinfo --noheader --Node --format=%t 2>/dev/null | grep -qx idle; then
    echo "SLURM_CONF=$dir/slurm.conf"
    exit 0
  fi
  sleep 0.2
done
echo "cluster.sh: the node did not become idle in 60 s" >&2
sinfo >&2 || true
tail -20 "$dir/slurmctld.log" "$dir/slurmd.log" >&2 || true
stop
exit 1
