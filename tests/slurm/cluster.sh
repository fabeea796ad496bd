#!/usr/bin/env bash
# A one-node Slurm cluster on this machine, for the sweep's end-to-end test (and for trying
# `hetsim sweep --slurm` by hand): Debian's slurm-wlm (22.05) with munge, run as root.
#
#   tests/slurm/cluster.sh start DIR   writes DIR/slurm.conf, starts munged (if no munged
#                                      answers), slurmctld and slurmd, waits for the node to
#                                      be idle; then `export SLURM_CONF=DIR/slurm.conf`
#   tests/slurm/cluster.sh stop DIR    stops the slurmctld and slurmd started in DIR (munged
#                                      stays: other users of munge may need it)
#
# ProctrackType=proctrack/linuxproc and TaskPlugin=task/none: no cgroups needed, so it runs
# in a container. State and spool folders live in DIR; nothing under /etc is written.
set -euo pipefail

usage() { echo "usage: $0 start|stop DIR" >&2; exit 2; }
[ $# -eq 2 ] || usage
action=$1
dir=$(mkdir -p "$2" && cd "$2" && pwd)

stop() {
    for d in slurmd slurmctld; do
        if [ -f "$dir/$d.pid" ]; then
            kill "$(cat "$dir/$d.pid")" 2>/dev/null || true
        fi
    done
    for _ in $(seq 50); do
        alive=0
        for d in slurmd slurmctld; do
            if [ -f "$dir/$d.pid" ] && kill -0 "$(cat "$dir/$d.pid")" 2>/dev/null; then alive=1; fi
        done
        [ $alive = 0 ] && break
        sleep 0.2
    done
    rm -f "$dir/slurmd.pid" "$dir/slurmctld.pid"
}

case "$action" in
stop) stop; exit 0 ;;
start) ;;
*) usage ;;
esac

for tool in munged slurmctld slurmd sinfo; do
    command -v "$tool" >/dev/null 2>&1 || {
        echo "cluster.sh: $tool not found: install Debian's slurm-wlm and munge (.ci/setup.sh does)" >&2
        exit 1
    }
done
[ "$(id -u)" = 0 ] || { echo "cluster.sh: slurmctld and slurmd run as root here (SlurmUser=root)" >&2; exit 1; }

# munge: the key the package made, and the daemon as its own user.
if ! (munge -n 2>/dev/null | unmunge >/dev/null 2>&1); then
    if [ ! -f /etc/munge/munge.key ]; then
        mungekey --create --keyfile=/etc/munge/munge.key
        chown munge:munge /etc/munge/munge.key
        chmod 0400 /etc/munge/munge.key
    fi
    mkdir -p /run/munge /var/log/munge /var/lib/munge
    chown munge:munge /run/munge /var/log/munge /var/lib/munge
    runuser -u munge -- /usr/sbin/munged
    for _ in $(seq 50); do
        (munge -n 2>/dev/null | unmunge >/dev/null 2>&1) && break
        sleep 0.1
    done
    (munge -n | unmunge >/dev/null) || { echo "cluster.sh: munged did not start" >&2; exit 1; }
fi

node=$(hostname -s)
cpus=$(nproc)
mkdir -p "$dir/state" "$dir/spool" "$dir/log"
cat > "$dir/slurm.conf" <<CONF
ClusterName=hetsim-test
SlurmctldHost=$node
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
SlurmctldPort=6817
SlurmdPort=6818
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/backfill
MpiDefault=none
ReturnToService=2
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MinJobAge=600
NodeName=$node CPUs=$cpus State=UNKNOWN
PartitionName=test Nodes=$node Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF="$dir/slurm.conf"
stop
rm -rf "$dir/state"/* "$dir/spool"/*
slurmctld -c -f "$SLURM_CONF"
slurmd -c -f "$SLURM_CONF"
for _ in $(seq 150); do
    state=$(sinfo -h -n "$node" -o %T 2>/dev/null || true)
    case "$state" in
    idle*) echo "cluster.sh: node $node idle; export SLURM_CONF=$SLURM_CONF"; exit 0 ;;
    esac
    sleep 0.2
done
echo "cluster.sh: node $node did not become idle (state: ${state:-none}); logs in $dir/log" >&2
tail -n 20 "$dir/log/slurmctld.log" "$dir/log/slurmd.log" >&2 || true
exit 1
