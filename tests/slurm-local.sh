#!/usr/bin/env bash
# tests/slurm-local.sh up|down|status: a one-node Slurm cluster on localhost (munge, slurmctld,
# slurmd) for the farm tests, without systemd. Idempotent. `up` installs the Debian packages if
# they are missing (as root); `down` cancels the jobs and stops only the daemons it started, by
# their recorded PIDs. Everything lives in $POSTHASTE_SLURM_DIR (default /tmp/posthaste-slurm);
# commands must see SLURM_CONF=$POSTHASTE_SLURM_DIR/slurm.conf (printed by `up` and `status`).
set -euo pipefail
STATE=${POSTHASTE_SLURM_DIR:-/tmp/posthaste-slurm}
CONF=$STATE/slurm.conf
export SLURM_CONF=$CONF

running() { [[ -f $1 ]] && kill -0 "$(cat "$1")" 2>/dev/null; }

install_packages() {
    local missing=()
    for p in slurmctld slurmd slurm-client munge; do
        dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" ||
            missing+=("$p")
    done
    if ((${#missing[@]})); then
        echo "slurm-local: installing ${missing[*]}"
        apt-get update -qq
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
            "${missing[@]}" >/dev/null
    fi
}

write_conf() {
    local node
    node=$(slurmd -C | head -n 1)
    cat >"$CONF" <<CONF
ClusterName=posthaste
SlurmctldHost=localhost
SlurmUser=root
AuthType=auth/munge
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerParameters=batch_sched_delay=0,kill_invalid_depend
MinJobAge=3600
MailProg=/bin/true
ReturnToService=2
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
StateSaveLocation=$STATE/state
SlurmdSpoolDir=$STATE/spool
SlurmctldPidFile=$STATE/slurmctld.pid
SlurmdPidFile=$STATE/slurmd.pid
SlurmctldLogFile=$STATE/log/slurmctld.log
SlurmdLogFile=$STATE/log/slurmd.log
$node NodeAddr=127.0.0.1 State=UNKNOWN
PartitionName=debug Nodes=ALL Default=YES MaxTime=INFINITE State=UP
CONF
}

up() {
    install_packages
    mkdir -p "$STATE/state" "$STATE/spool" "$STATE/log"
    if ! pgrep -x munged >/dev/null; then
        mkdir -p /run/munge
        chown munge:munge /run/munge
        # munged forks into the background: its own PID file names the daemon, not the parent
        # pgrep might catch before the fork (which left a munged running after `down`).
        rm -f /run/munge/posthaste-munged.pid
        runuser -u munge -- munged --pid-file=/run/munge/posthaste-munged.pid
        for _ in $(seq 1 50); do
            [[ -s /run/munge/posthaste-munged.pid ]] && break
            sleep 0.1
        done
        cp /run/munge/posthaste-munged.pid "$STATE/munged.pid"
    fi
    [[ -f $CONF ]] || write_conf
    running "$STATE/slurmctld.pid" || slurmctld -f "$CONF"
    running "$STATE/slurmd.pid" || slurmd -f "$CONF"
    for _ in $(seq 1 60); do
        if sinfo -h -o %t 2>/dev/null | grep -qE '^(idle|mix|alloc)'; then
            echo "slurm-local: up; export SLURM_CONF=$CONF"
            return 0
        fi
        sleep 0.5
    done
    echo "slurm-local: the node did not become idle (logs in $STATE/log)" >&2
    return 1
}

down() {
    if running "$STATE/slurmctld.pid"; then
        scancel --full -u "$(id -un)" 2>/dev/null || true
        sleep 1  # a job's slurmstepd outlives slurmd on TERM: cancel first
    fi
    local pids=()
    for d in slurmd slurmctld munged; do
        if running "$STATE/$d.pid"; then
            pids+=("$(cat "$STATE/$d.pid")")
            kill "${pids[-1]}" 2>/dev/null || true
        fi
        rm -f "$STATE/$d.pid"
    done
    for pid in "${pids[@]}"; do  # gone before `down` returns (at most 10 s each)
        for _ in $(seq 1 100); do
            kill -0 "$pid" 2>/dev/null || break
            sleep 0.1
        done
    done
    echo "slurm-local: down"
}

status() {
    for d in munged slurmctld slurmd; do
        if running "$STATE/$d.pid" || { [[ $d == munged ]] && pgrep -x munged >/dev/null; }; then
            echo "$d: running"
        else
            echo "$d: stopped"
        fi
    done
    sinfo 2>/dev/null || true
    echo "export SLURM_CONF=$CONF"
}

case "${1:-}" in
    up) up ;;
    down) down ;;
    status) status ;;
    *) echo "usage: $0 up|down|status" >&2; exit 2 ;;
esac
