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

# The pid in DIR/<daemon>.pid, if that process is still this cluster's daemon (its command
# line names DIR's slurm.conf): a stale pid file never kills someone else's process.
ours() {
    local pid
    [ -f "$dir/$1.pid" ] || return 1
    pid=$(cat "$dir/$1.pid")
    [ -n "$pid" ] || return 1
    # The process is that daemon (its name) started with this folder's configuration.
    [ "$(cat "/proc/$pid/comm" 2>/dev/null)" = "$1" ] || return 1
    tr '\0' ' ' < "/proc/$pid/cmdline" 2>/dev/null | grep -qF -- "-f $dir/slurm.conf" || return 1
    echo "$pid"
}

stop() {
    for d in slurmd slurmctld; do
        if pid=$(ours $d); then
            kill "$pid" 2>/dev/null || true
        fi
    done
    for i in $(seq 60); do
        alive=0
        for d in slurmd slurmctld; do
            if pid=$(ours $d); then
                alive=1
                # Still there after 10 s: killed.
                [ "$i" -gt 50 ] && kill -KILL "$pid" 2>/dev/null
            fi
        done
        [ $alive = 0 ] && break
        sleep 0.2
    done
    if [ $alive = 1 ]; then
        echo "cluster.sh: the daemons started in $dir did not stop" >&2
        return 1
    fi
    rm -f "$dir/slurmd.pid" "$dir/slurmctld.pid"
}

case "$action" in
stop) stop; exit 0 ;;
start) ;;
*) usage ;;
esac

for tool in munged slurmctld slurmd sinfo ss; do
    command -v "$tool" >/dev/null 2>&1 || {
        echo "cluster.sh: $tool not found: install Debian's slurm-wlm, munge and iproute2 (.ci/setup.sh does)" >&2
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
# Two free TCP ports, so a cluster already running on this machine (Slurm's default 6817/6818,
# or another test's) is neither used by mistake nor disturbed.
listening() { ss -Htln "sport = :$1" 2>/dev/null | grep -q . ; }
port=""
for p in $(seq 16817 10 17807); do
    if ! listening "$p" && ! listening $((p + 1)); then port=$p; break; fi
done
[ -n "$port" ] || { echo "cluster.sh: no two free TCP ports in 16817-17808" >&2; exit 1; }
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
SlurmctldPort=$port
SlurmdPort=$((port + 1))
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
    # Our own daemons, alive, and the controller that answers is ours (its state folder).
    if ours slurmctld >/dev/null && ours slurmd >/dev/null \
        && scontrol show config 2>/dev/null | grep -q "StateSaveLocation *= *$dir/state"; then
        state=$(sinfo -h -n "$node" -o %T 2>/dev/null || true)
        case "$state" in
        idle*) echo "cluster.sh: node $node idle (ports $port, $((port + 1))); export SLURM_CONF=$SLURM_CONF"; exit 0 ;;
        esac
    fi
    sleep 0.2
done
echo "cluster.sh: node $node did not become idle (state: ${state:-none}); logs in $dir/log" >&2
tail -n 20 "$dir/log/slurmctld.log" "$dir/log/slurmd.log" >&2 || true
stop || true
exit 1
