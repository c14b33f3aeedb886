#!/bin/bash
# A private one-node Slurm (22.05) cluster with its own MUNGE, for the farm
# test (tests/farm/test_slurm.py, docs/farm.md).
#
#   slurm_cluster.sh start DIR   make DIR, start munged, slurmctld and slurmd, wait for the node to be idle
#   slurm_cluster.sh stop  DIR   cancel the jobs, stop the daemons by the PIDs recorded at start, wait
#   slurm_cluster.sh env   DIR   print the "export SLURM_CONF=..." line for clients
#
# Everything (key, sockets, state, spool, logs, pid files, config) lives inside DIR.
# Clients only need:  export SLURM_CONF=DIR/slurm.conf
# (the munge socket is taken from AuthInfo=socket=... in that file; no munge env var exists/needed).
#
# Must run as root (SlurmUser=root, SlurmdUser=root). Nothing outside DIR is touched.
set -euo pipefail

# Env knobs: START_TIMEOUT, STOP_TIMEOUT, SLURM_EXTRA_CONF (lines appended to slurm.conf)
START_TIMEOUT=${START_TIMEOUT:-60}   # seconds to wait for the node to become idle
STOP_TIMEOUT=${STOP_TIMEOUT:-30}     # seconds to wait for each daemon to exit

die() { echo "slurm_cluster.sh: ERROR: $*" >&2; exit 1; }
log() { echo "slurm_cluster.sh: $*" >&2; }

# alive PID [COMM]: PID exists, is not a zombie (init may reap orphans lazily), and,
# if COMM is given, is that program (guards against PID reuse after a reboot/crash).
alive() {
    local pid=$1 comm=${2:-} st
    [[ -n "$pid" && -e /proc/$pid ]] || return 1
    st=$(awk '{print $3}' "/proc/$pid/stat" 2>/dev/null) || return 1
    [[ -n "$st" && "$st" != Z && "$st" != X ]] || return 1
    [[ -z "$comm" || "$(cat "/proc/$pid/comm" 2>/dev/null)" == "$comm" ]]
}

# Is a TCP port free (nothing listening, nothing bound) on this host?
port_free() {
    ! ss -Htan 2>/dev/null | awk '{print $4}' | grep -qE "[:.]$1\$"
}

pick_ports() {  # prints "CTLD_PORT SLURMD_PORT": two consecutive free ports in 20000-40000
    local p i
    for i in $(seq 1 200); do
        p=$(( 20000 + RANDOM % 19999 ))
        if port_free "$p" && port_free $((p + 1)); then echo "$p $((p + 1))"; return 0; fi
    done
    die "could not find free ports in 20000-40000"
}

dump_logs() {
    local d=$1 f
    for f in munged.log slurmctld.log slurmctld.out slurmd.log slurmd.out; do
        [[ -s "$d/$f" ]] || continue
        echo "===== $d/$f (last 40 lines) =====" >&2
        tail -n 40 "$d/$f" >&2
    done
}

# Launch "$@" in the background in its own session, stdio detached (so a harness that
# captures our stdout does not hang on it), and print its PID.
launch() {
    local out=$1; shift
    setsid "$@" </dev/null >>"$out" 2>&1 &
    echo $!
}

# Startup failed: show the logs, tear down whatever was already started, exit 1.
fail() {
    local D=$1; shift
    dump_logs "$D"
    log "startup failed, stopping what was started"
    cmd_stop "$D" || true
    die "$*"
}

cmd_start() {
    local D=$1 host ncpu memmb realmem ctld_port slurmd_port pid i state
    [[ $EUID -eq 0 ]] || die "must run as root"
    mkdir -p "$D"
    D=$(cd "$D" && pwd -P)
    # munged refuses a socket dir that is not world-executable (mktemp -d gives 0700).
    chmod 0755 "$D"

    # Refuse to start over a live cluster; otherwise wipe stale state from a previous run.
    for f in munged slurmctld slurmd; do
        if [[ -f "$D/$f.pid.launch" ]] && alive "$(cat "$D/$f.pid.launch")" "$f"; then
            die "$f (pid $(cat "$D/$f.pid.launch")) from a previous start is still running in $D; run: $0 stop $D"
        fi
    done
    rm -rf "$D/state" "$D/spool" "$D"/munge.* "$D"/munged.* "$D"/slurm*.pid "$D"/slurm*.log \
           "$D"/slurm*.out "$D"/*.pid.launch "$D/slurm.conf" "$D/jobcomp.txt" "$D/env.sh"
    mkdir -p "$D/state" "$D/spool"
    chmod 0700 "$D/state"

    # ---------------- MUNGE ----------------
    mungekey --create --keyfile="$D/munge.key" --bits=1024 >/dev/null 2>&1 \
        || dd if=/dev/urandom of="$D/munge.key" bs=128 count=1 status=none
    chmod 0400 "$D/munge.key"
    # munged daemonizes itself only once its socket is ready; it then honours --log-file.
    # (--force: tolerate e.g. a stale socket/lock; as root it is not otherwise needed.)
    munged --force --socket="$D/munge.socket" --key-file="$D/munge.key" \
           --pid-file="$D/munged.pid" --log-file="$D/munged.log" --seed-file="$D/munged.seed" \
           </dev/null >"$D/munged.out" 2>&1 \
        || { fail "$D" "munged failed to start"; }
    pid=$(cat "$D/munged.pid" 2>/dev/null || true)
    alive "$pid" munged || { fail "$D" "munged not running after start (pid '$pid')"; }
    echo "$pid" >"$D/munged.pid.launch"
    munge -n -S "$D/munge.socket" | unmunge -S "$D/munge.socket" >/dev/null \
        || { fail "$D" "munge/unmunge self-test against $D/munge.socket failed"; }

    # ---------------- slurm.conf ----------------
    host=$(hostname -s)
    ncpu=$(nproc)
    # Use slurmd's own hardware view for the socket/core layout when it agrees with nproc
    # (plain CPUs=N works too, but slurmd then logs "Node reconfigured socket/core boundaries").
    local topo="CPUs=$ncpu" hw
    hw=$(slurmd -C 2>/dev/null | head -n1 || true)
    if [[ "$hw" =~ CPUs=$ncpu\  ]]; then
        topo=$(sed -E 's/^NodeName=[^ ]+ //; s/ RealMemory=.*//' <<<"$hw")
    fi
    memmb=$(awk '/^MemTotal:/ {print int($2/1024)}' /proc/meminfo)
    realmem=$(( memmb * 90 / 100 ))          # a bit below the machine's, else node -> INVAL
    read -r ctld_port slurmd_port < <(pick_ports) || true
    [[ -n "${slurmd_port:-}" ]] || fail "$D" "could not find two free TCP ports in 20000-40000"
    cat >"$D/slurm.conf" <<EOF
# generated by slurm_cluster.sh for a private test cluster in $D
ClusterName=curvenet$(( RANDOM % 100000 ))
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$D/munge.socket
StateSaveLocation=$D/state
SlurmdSpoolDir=$D/spool
SlurmctldPidFile=$D/slurmctld.pid
SlurmdPidFile=$D/slurmd.pid
SlurmctldLogFile=$D/slurmctld.log
SlurmdLogFile=$D/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
MpiDefault=none
SwitchType=switch/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/backfill
# bf_interval=1: backfill every 1s instead of 30s -> queued array tasks start ~2s sooner
SchedulerParameters=bf_interval=1
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/filetxt
JobCompLoc=$D/jobcomp.txt
ReturnToService=2
MinJobAge=300
KillWait=5
SlurmdTimeout=60
InactiveLimit=0
MailProg=/bin/true
NodeName=$host NodeAddr=127.0.0.1 $topo RealMemory=$realmem State=UNKNOWN
PartitionName=debug Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
    # optional extra lines (e.g. SchedulerParameters=...) from the caller
    if [[ -n "${SLURM_EXTRA_CONF:-}" ]]; then printf '%s\n' "$SLURM_EXTRA_CONF" >>"$D/slurm.conf"; fi
    echo "export SLURM_CONF=$D/slurm.conf" >"$D/env.sh"
    export SLURM_CONF="$D/slurm.conf"

    # ---------------- slurmctld + slurmd ----------------
    # -D: stay in foreground, so $! is the daemon's real PID (no pid-file race).
    pid=$(launch "$D/slurmctld.out" env SLURM_CONF="$D/slurm.conf" slurmctld -D -f "$D/slurm.conf")
    echo "$pid" >"$D/slurmctld.pid.launch"
    # wait until slurmctld answers
    for i in $(seq 1 $(( START_TIMEOUT * 4 ))); do
        scontrol ping 2>/dev/null | grep -q 'is UP' && break
        alive "$pid" || { fail "$D" "slurmctld exited during startup"; }
        sleep 0.25
    done
    pid=$(launch "$D/slurmd.out" env SLURM_CONF="$D/slurm.conf" CURVENET_SLURM_DIR="$D" \
            slurmd -D -f "$D/slurm.conf")
    echo "$pid" >"$D/slurmd.pid.launch"

    # ---------------- wait for node idle ----------------
    for i in $(seq 1 $(( START_TIMEOUT * 4 ))); do
        state=$(sinfo -h -n "$host" -o '%t' 2>/dev/null | head -n1 || true)
        [[ "$state" == idle ]] && break
        alive "$(cat "$D/slurmctld.pid.launch")" || { fail "$D" "slurmctld died"; }
        alive "$(cat "$D/slurmd.pid.launch")"    || { fail "$D" "slurmd died"; }
        sleep 0.25
    done
    if [[ "$state" != idle ]]; then
        sinfo -N -l >&2 || true
        scontrol show node "$host" >&2 || true
        fail "$D" "node $host not idle after ${START_TIMEOUT}s (state='$state')"
    fi
    # the pid files written by the daemons must agree with what we launched
    for f in slurmctld slurmd; do
        if [[ -f "$D/$f.pid" && "$(cat "$D/$f.pid")" != "$(cat "$D/$f.pid.launch")" ]]; then
            log "warning: $f.pid ($(cat "$D/$f.pid")) != launched pid ($(cat "$D/$f.pid.launch"))"
        fi
    done
    log "cluster up in $D (ctld port $ctld_port, slurmd port $slurmd_port, node $host: idle)"
    log "clients: export SLURM_CONF=$D/slurm.conf"
}

# PIDs of slurmstepd processes belonging to this cluster (they are double-forked by slurmd,
# so not its children; identified by the CURVENET_SLURM_DIR marker they inherit from slurmd).
stepd_pids() {
    local D=$1 p
    for p in $(pgrep -x slurmstepd 2>/dev/null || true); do
        { tr '\0' '\n' <"/proc/$p/environ"; } 2>/dev/null | grep -qxF "CURVENET_SLURM_DIR=$D" && echo "$p"
    done
    return 0
}

stop_pid() {  # stop_pid NAME PID : TERM, wait, then KILL
    local name=$1 pid=$2 i
    alive "$pid" "$name" || return 0
    kill -TERM "$pid" 2>/dev/null || true
    for i in $(seq 1 $(( STOP_TIMEOUT * 10 ))); do
        alive "$pid" || { log "$name (pid $pid) stopped"; return 0; }
        sleep 0.1
    done
    log "$name (pid $pid) did not exit after ${STOP_TIMEOUT}s, sending SIGKILL"
    kill -KILL "$pid" 2>/dev/null || true
    for i in $(seq 1 50); do alive "$pid" || return 0; sleep 0.1; done
    log "warning: $name (pid $pid) still present"
    return 1
}

cmd_stop() {
    local D=$1 rc=0 pid i p
    [[ -d "$D" ]] || die "no such directory: $D"
    D=$(cd "$D" && pwd -P)
    export SLURM_CONF="$D/slurm.conf"
    # 1. cancel remaining jobs while slurmctld/slurmd are still up so job steps are cleaned
    if [[ -f "$D/slurmctld.pid.launch" ]] && alive "$(cat "$D/slurmctld.pid.launch")" slurmctld; then
        local jobs
        jobs=$(squeue -h -o %F 2>/dev/null | sort -u || true)   # %F = array job id / job id
        if [[ -n "$jobs" ]]; then
            # shellcheck disable=SC2086
            scancel $jobs 2>/dev/null || true
            for i in $(seq 1 100); do
                [[ -z "$(squeue -h -o %i 2>/dev/null)" ]] && break
                sleep 0.2
            done
        fi
    fi
    # 2. daemons, in reverse start order, by recorded PID
    for f in slurmd slurmctld; do
        [[ -f "$D/$f.pid.launch" ]] || continue
        alive "$(cat "$D/$f.pid.launch")" "$f" || continue
        stop_pid "$f" "$(cat "$D/$f.pid.launch")" || rc=1
    done
    # 3. any leftover slurmstepd of this cluster
    for p in $(stepd_pids "$D"); do stop_pid slurmstepd "$p" || rc=1; done
    # 4. munged last (slurmd/slurmctld need it while shutting down)
    if [[ -f "$D/munged.pid.launch" ]]; then
        stop_pid munged "$(cat "$D/munged.pid.launch")" || rc=1
    fi
    [[ $rc -eq 0 ]] && rm -f "$D"/*.pid.launch
    return $rc
}

case "${1:-}" in
    start) [[ $# -eq 2 ]] || die "usage: $0 start DIR"; cmd_start "$2" ;;
    stop)  [[ $# -eq 2 ]] || die "usage: $0 stop DIR";  cmd_stop "$2" ;;
    env)   [[ $# -eq 2 ]] || die "usage: $0 env DIR";   echo "export SLURM_CONF=$(cd "$2" && pwd -P)/slurm.conf" ;;
    *) echo "usage: $0 {start|stop|env} DIR" >&2; exit 2 ;;
esac
