#!/usr/bin/env bash
# Throwaway single-node Slurm cluster on localhost, for automated tests.
#
#   local_cluster.sh start DIR   # prints: export SLURM_CONF=DIR/slurm.conf
#   local_cluster.sh stop DIR    # idempotent, also after a failed start
#
# Or source it and call `local_cluster start|stop DIR`. Everything (munge key
# and socket, slurm.conf, state, logs, pid files) lives under DIR, so
# /etc/slurm, /etc/munge and the system munge socket are never used and
# clusters in different DIRs do not clash. Needs root (SlurmUser=root).
# Written for Debian 12: slurm-wlm 22.05, munge 0.5.15.
# A finished job: `squeue -h -j ID` prints nothing (exit 0) until MinJobAge
# purges it, then "Invalid job id specified" (exit 1); an unreachable
# controller gives "Unable to contact slurm controller" (exit 1, after ~10 s).

# Daemons we start, in stop order: name:pidfile:logfile (relative to DIR).
_lc_daemons=(slurmd:run/slurmd.pid:log/slurmd.log
    slurmctld:run/slurmctld.pid:log/slurmctld.log
    munged:munge/munged.pid:munge/munged.log)

# Prints two TCP ports nobody listens on; a random base keeps parallel runs apart.
_lc_free_ports() {
    local p=$((20000 + RANDOM % 30000)) found=()
    for ((; ${#found[@]} < 2 && p < 65000; p++)); do
        if command -v ss >/dev/null; then ss -Hltn "sport = :$p" | grep -q . && continue
        elif (exec 3<>"/dev/tcp/127.0.0.1/$p") 2>/dev/null; then continue; fi
        found+=("$p")
    done
    ((${#found[@]} == 2)) && echo "${found[@]}"
}

_lc_stop() {
    local dir entry name pidf pid p i sid pids=()
    dir=$(cd "$1" 2>/dev/null && pwd) || return 0
    # Running job steps outlive slurmd. Ours inherited our SLURM_CONF, so find
    # them by it and kill each one's session (stepd + job script + children).
    for p in $(pgrep -x slurmstepd); do
        tr '\0' '\n' 2>/dev/null <"/proc/$p/environ" | grep -qxF "SLURM_CONF=$dir/slurm.conf" || continue
        sid=$(ps -o sid= -p "$p") || continue
        # shellcheck disable=SC2046 # a list of pids
        kill -KILL $(ps -o pid= -s "${sid// /}") 2>/dev/null
    done
    for entry in "${_lc_daemons[@]}"; do
        IFS=: read -r name pidf _ <<<"$entry"
        [[ -s $dir/$pidf ]] || continue
        pid=$(<"$dir/$pidf")
        rm -f "$dir/$pidf"
        # Signal only if the pid still belongs to that daemon (pid reuse).
        [[ $pid =~ ^[0-9]+$ && $(cat "/proc/$pid/comm" 2>/dev/null) == "$name" ]] &&
            kill -TERM "$pid" 2>/dev/null && pids+=("$pid")
    done
    # Each daemon needs ~2 s to exit, so wait for all of them together.
    for ((i = 0; i < 100 && ${#pids[@]}; i++)); do
        kill -0 "${pids[@]}" 2>/dev/null || break   # succeeds while any is alive
        sleep 0.1
    done
    for pid in "${pids[@]}"; do kill -KILL "$pid" 2>/dev/null; done
    return 0
}

# Report a failed start with the tail of the relevant log, then tear down.
_lc_fail() {
    local dir=$1 log=$2
    echo "local_cluster: start failed: $3" >&2
    [[ -f $log ]] && { echo "--- tail of $log ---"; tail -n 30 "$log"; } >&2
    _lc_stop "$dir"
    return 1
}

_lc_start() {
    local dir host cpus ports ctld_port d_port state entry name pidf log t0=$SECONDS
    ((EUID == 0)) || { echo "local_cluster: must run as root" >&2; return 1; }
    mkdir -p "$1" && dir=$(cd "$1" && pwd) || return 1
    _lc_stop "$dir"                  # leftovers of an earlier run in DIR
    rm -rf "$dir/spool" "$dir/log"   # else slurmctld would recover old jobs
    # munged refuses a socket unless every directory on its path is
    # executable by all (mktemp -d gives 0700), and wants a private key dir.
    mkdir -p "$dir"/{munge,munge-sock,run,log,spool/ctld,spool/d} && chmod go+x "$dir" &&
        chmod 700 "$dir/munge" && chmod 755 "$dir/munge-sock" || return 1
    [[ -s $dir/munge/munge.key ]] || mungekey -c -k "$dir/munge/munge.key" || return 1

    local sock=$dir/munge-sock/munge.socket
    munged --socket="$sock" --key-file="$dir/munge/munge.key" \
        --log-file="$dir/munge/munged.log" --pid-file="$dir/munge/munged.pid" \
        --seed-file="$dir/munge/munged.seed" ||
        _lc_fail "$dir" "$dir/munge/munged.log" "munged did not start" || return 1

    host=$(hostname -s) cpus=$(nproc)
    ports=$(_lc_free_ports) || _lc_fail "$dir" "" "no free TCP ports" || return 1
    read -r ctld_port d_port <<<"$ports"
    # AuthInfo=socket= is read by auth/munge and cred/munge in the daemons and
    # in every client, so only our munged is ever contacted. linuxproc +
    # task/none load no cgroup plugin, so no cgroup.conf is needed. The empty
    # plugstack.conf keeps /etc/slurm/plugstack.conf (SPANK plugins) out.
    # CR_CPU: one task per CPU even on SMT hosts (CR_Core would take a core).
    # batch_sched_delay=0: schedule at once on submit instead of after 3 s.
    : >"$dir/plugstack.conf"
    cat >"$dir/slurm.conf" <<EOF
ClusterName=localtest
SlurmctldHost=$host(127.0.0.1)
SlurmUser=root
SlurmdUser=root
SlurmctldPort=$ctld_port
SlurmdPort=$d_port
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$sock
PlugStackConfig=$dir/plugstack.conf
StateSaveLocation=$dir/spool/ctld
SlurmdSpoolDir=$dir/spool/d
SlurmctldPidFile=$dir/run/slurmctld.pid
SlurmdPidFile=$dir/run/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SchedulerType=sched/builtin
SchedulerParameters=batch_sched_delay=0
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
MpiDefault=none
MailProg=/bin/true
ReturnToService=2
MinJobAge=2
NodeName=$host NodeAddr=127.0.0.1 CPUs=$cpus State=UNKNOWN
PartitionName=debug Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
    # Exported for sinfo and so slurmstepd inherits it (see _lc_stop);
    # "local" keeps it out of a shell that sourced this file.
    local -x SLURM_CONF=$dir/slurm.conf
    slurmctld -f "$SLURM_CONF" ||
        _lc_fail "$dir" "$dir/log/slurmctld.log" "slurmctld did not start" || return 1
    slurmd -f "$SLURM_CONF" -N "$host" ||
        _lc_fail "$dir" "$dir/log/slurmd.log" "slurmd did not start" || return 1

    # Clients retry an unreachable controller for ~10 s (MessageTimeout), so
    # check the daemons first and bound each sinfo.
    local t1=$SECONDS
    while ((SECONDS - t1 < 30)); do
        for entry in "${_lc_daemons[@]}"; do   # pid files appear just after the fork
            IFS=: read -r name pidf log <<<"$entry"
            ((SECONDS - t1 < 2)) || kill -0 "$(cat "$dir/$pidf" 2>/dev/null)" 2>/dev/null ||
                _lc_fail "$dir" "$dir/$log" "$name exited" || return 1
        done
        state=$(timeout 5 sinfo -h -n "$host" -o %t 2>/dev/null)
        [[ $state == idle ]] && break
        sleep 0.2
    done
    [[ $state == idle ]] || _lc_fail "$dir" "$dir/log/slurmd.log" \
        "node $host not idle after 30 s (state: '${state:-none}')" || return 1
    echo "local_cluster: up in $((SECONDS - t0)) s, ports $ctld_port/$d_port" >&2
    echo "export SLURM_CONF=$dir/slurm.conf"
}

local_cluster() {
    case "$1:$2" in
        start:?*) _lc_start "$2" ;;
        stop:?*) _lc_stop "$2" ;;
        *) echo "usage: local_cluster.sh {start|stop} DIR" >&2 && return 2 ;;
    esac
}

# Run when executed, not when sourced.
[[ ${BASH_SOURCE[0]} != "$0" ]] || local_cluster "$@"
