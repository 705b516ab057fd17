#!/usr/bin/env bash
# A one-node Slurm cluster on this machine, for the Slurm integration test and for trying the
# templates: `slurm/local-cluster.sh start DIR` writes a config under DIR, starts munged (as the
# munge user), slurmctld and slurmd (as root), and waits until the node is idle;
# `slurm/local-cluster.sh stop DIR` stops what start started. Needs root and Debian's
# slurm-wlm and munge packages. The config: proctrack/linuxproc, task/none,
# select/cons_tres, every core and 90 % of the memory of this machine on node `localhost`.
set -euo pipefail
cmd=${1:?usage: local-cluster.sh start|stop DIR}
dir=$(realpath -m "${2:?usage: local-cluster.sh start|stop DIR}")
case "$cmd" in
start)
    mkdir -p "$dir"/{state,spool,log}
    cpus=$(nproc)
    mem=$(awk '/MemTotal/ {printf "%d", $2 / 1024 * 0.9}' /proc/meminfo)
    cat > "$dir/slurm.conf" <<CONF
ClusterName=scatterbench
SlurmctldHost=localhost
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
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
SelectTypeParameters=CR_Core_Memory
SchedulerType=sched/backfill
MpiDefault=none
ReturnToService=2
SlurmctldTimeout=30
SlurmdTimeout=30
InactiveLimit=0
MinJobAge=300
KillWait=10
Waittime=0
JobCompType=jobcomp/none
AccountingStorageType=accounting_storage/none
DefMemPerCPU=1024
NodeName=localhost CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=debug Nodes=localhost Default=YES MaxTime=INFINITE State=UP
CONF
    # munge: a key if there is none, the daemon as the munge user.
    if [ ! -s /etc/munge/munge.key ]; then
        dd if=/dev/urandom bs=1 count=1024 of=/etc/munge/munge.key status=none
        chown munge:munge /etc/munge/munge.key
        chmod 400 /etc/munge/munge.key
    fi
    mkdir -p /run/munge /var/log/munge /var/lib/munge
    chown munge:munge /run/munge /var/log/munge /var/lib/munge
    if ! pgrep -x munged >/dev/null; then
        runuser -u munge -- /usr/sbin/munged
        touch "$dir/started-munged"
    fi
    export SLURM_CONF=$dir/slurm.conf
    /usr/sbin/slurmctld -f "$SLURM_CONF"
    /usr/sbin/slurmd -f "$SLURM_CONF"
    for _ in $(seq 60); do
        if sinfo -h -o %T 2>/dev/null | grep -qx idle; then
            echo "slurm: node localhost idle ($cpus CPUs, $mem MB); export SLURM_CONF=$SLURM_CONF"
            exit 0
        fi
        sleep 0.5
    done
    echo "slurm: the node did not come up; logs in $dir/log" >&2
    tail -20 "$dir"/log/*.log >&2 || true
    exit 1
    ;;
stop)
    for d in slurmd slurmctld; do
        if [ -s "$dir/$d.pid" ]; then kill "$(cat "$dir/$d.pid")" 2>/dev/null || true; fi
    done
    if [ -e "$dir/started-munged" ]; then pkill -x munged || true; rm -f "$dir/started-munged"; fi
    for _ in $(seq 40); do
        [ -e "$dir/slurmd.pid" ] || [ -e "$dir/slurmctld.pid" ] || break
        sleep 0.25
    done
    ;;
*)
    echo "usage: local-cluster.sh start|stop DIR" >&2
    exit 2
    ;;
esac
