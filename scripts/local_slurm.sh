#!/usr/bin/env bash
# A real single-node SLURM cluster on this machine, for tests and benchmarks of the workflow's cluster path:
# Debian's slurm-wlm (slurmctld, slurmd, slurmdbd for sacct) with munge and a MariaDB accounting database,
# all under one state folder, all on the loopback interface.
#
#   bash scripts/local_slurm.sh start    # install the Debian packages if missing (needs root), start, wait until idle
#   bash scripts/local_slurm.sh status   # sinfo of the node, or "stopped"
#   bash scripts/local_slurm.sh stop     # end exactly the daemons this script started
#   bash scripts/local_slurm.sh env      # the line to eval before sbatch/sinfo/sacct/snakemake --profile profiles/slurm
#
# State folder: $PPM_SLURM_DIR (default /tmp/ppm-slurm): slurm.conf (this host's real CPU count and memory),
# slurmdbd.conf, the database, spool and state folders, logs and the pid files of the daemons started here.
# Partition "compute" (the default of profiles/slurm), account "ppm".
set -euo pipefail

STATE="${PPM_SLURM_DIR:-/tmp/ppm-slurm}"
HOST="$(hostname -s)"
DB_PORT="${PPM_SLURM_DB_PORT:-3307}"
PACKAGES=(slurm-wlm slurmdbd munge mariadb-server mariadb-client)

log() { echo "local_slurm: $*" >&2; }
die() { log "$*"; exit 1; }

running() { [ -f "$STATE/$1.pid" ] && kill -0 "$(cat "$STATE/$1.pid")" 2>/dev/null; }

install_packages() {
    local missing=()
    for package in "${PACKAGES[@]}"; do
        dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q "install ok installed" || missing+=("$package")
    done
    [ ${#missing[@]} -eq 0 ] && return 0
    [ "$(id -u)" -eq 0 ] || die "Debian packages ${missing[*]} are missing; install them as root (apt-get install ${missing[*]})"
    command -v apt-get >/dev/null || die "no apt-get here: install ${missing[*]} (SLURM 22.05+, munge, MariaDB) yourself"
    log "installing ${missing[*]}"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq >/dev/null
    # no service start from package scripts: this script starts what it needs itself
    printf '#!/bin/sh\nexit 101\n' > /usr/sbin/policy-rc.d && chmod +x /usr/sbin/policy-rc.d
    apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null || { rm -f /usr/sbin/policy-rc.d; die "apt-get install ${missing[*]} failed"; }
    rm -f /usr/sbin/policy-rc.d
}

wait_for() {  # wait_for SECONDS DESCRIPTION COMMAND...
    local seconds="$1" what="$2"; shift 2
    for _ in $(seq 1 "$seconds"); do "$@" >/dev/null 2>&1 && return 0; sleep 1; done
    die "$what did not come up within ${seconds} s (logs in $STATE/log)"
}

write_configs() {
    local cpus memory_mb
    cpus="$(nproc)"
    # the node's memory as slurmd measures it, less 5 % so that the node is never drained for "low RealMemory"
    memory_mb="$(awk '/MemTotal/ {print int($2 / 1024 * 0.95)}' /proc/meminfo)"
    mkdir -p "$STATE"/{log,ctld,spool,mysql,run}
    cat > "$STATE/slurm.conf" <<EOF
# written by scripts/local_slurm.sh for host $HOST ($cpus CPUs, $memory_mb MB)
ClusterName=ppmlocal
SlurmctldHost=$HOST(127.0.0.1)
SlurmUser=root
SlurmdUser=root
SlurmctldPort=6817
SlurmdPort=6818
AuthType=auth/munge
StateSaveLocation=$STATE/ctld
SlurmdSpoolDir=$STATE/spool
SlurmctldPidFile=$STATE/run/slurmctld.pid
SlurmdPidFile=$STATE/run/slurmd.pid
SlurmctldLogFile=$STATE/log/slurmctld.log
SlurmdLogFile=$STATE/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/linux
JobAcctGatherFrequency=2
AccountingStorageType=accounting_storage/slurmdbd
AccountingStorageHost=127.0.0.1
AccountingStoragePort=6819
AccountingStorageEnforce=associations
JobCompType=jobcomp/none
AccountingStoreFlags=job_comment
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
ReturnToService=2
MinJobAge=3600
MpiDefault=none
NodeName=$HOST NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$memory_mb State=UNKNOWN
PartitionName=compute Nodes=ALL Default=YES MaxTime=INFINITE State=UP
EOF
    cat > "$STATE/slurmdbd.conf" <<EOF
# written by scripts/local_slurm.sh
DbdHost=$HOST
DbdAddr=127.0.0.1
DbdPort=6819
SlurmUser=root
AuthType=auth/munge
StorageType=accounting_storage/mysql
StorageHost=127.0.0.1
StoragePort=$DB_PORT
StorageUser=slurm
StoragePass=slurm
StorageLoc=slurm_acct_db
PidFile=$STATE/run/slurmdbd.pid
LogFile=$STATE/log/slurmdbd.log
EOF
    chmod 600 "$STATE/slurmdbd.conf"
}

start_munge() {
    if pgrep -x munged >/dev/null; then return 0; fi
    [ -s /etc/munge/munge.key ] || { mkdir -p /etc/munge; dd if=/dev/urandom of=/etc/munge/munge.key bs=1024 count=1 status=none; }
    chown -R munge:munge /etc/munge 2>/dev/null || true
    chmod 400 /etc/munge/munge.key
    mkdir -p /run/munge /var/lib/munge /var/log/munge && chown munge:munge /run/munge /var/lib/munge /var/log/munge 2>/dev/null || true
    if id munge >/dev/null 2>&1; then
        su -s /bin/sh munge -c "munged --pid-file=/run/munge/munged.pid" || die "munged did not start"
    else
        munged --force --pid-file=/run/munge/munged.pid || die "munged did not start"
    fi
    wait_for 20 munged test -f /run/munge/munged.pid
    cp /run/munge/munged.pid "$STATE/munged.pid"
}

start_database() {
    running mariadbd && return 0
    if [ ! -d "$STATE/mysql/mysql" ]; then
        mariadb-install-db --no-defaults --user=root --datadir="$STATE/mysql" --auth-root-authentication-method=socket \
            > "$STATE/log/mariadb-install.log" 2>&1 || die "mariadb-install-db failed ($STATE/log/mariadb-install.log)"
    fi
    mariadbd --no-defaults --user=root --datadir="$STATE/mysql" --socket="$STATE/run/mysql.sock" \
        --bind-address=127.0.0.1 --port="$DB_PORT" --pid-file="$STATE/run/mariadbd.pid" \
        --log-error="$STATE/log/mariadb.log" --innodb-buffer-pool-size=256M --innodb-lock-wait-timeout=900 &
    echo $! > "$STATE/mariadbd.pid"
    wait_for 60 MariaDB mariadb --no-defaults --socket="$STATE/run/mysql.sock" -e "select 1"
    mariadb --no-defaults --socket="$STATE/run/mysql.sock" <<EOF
CREATE DATABASE IF NOT EXISTS slurm_acct_db;
CREATE USER IF NOT EXISTS 'slurm'@'127.0.0.1' IDENTIFIED BY 'slurm';
CREATE USER IF NOT EXISTS 'slurm'@'localhost' IDENTIFIED BY 'slurm';
GRANT ALL ON slurm_acct_db.* TO 'slurm'@'127.0.0.1';
GRANT ALL ON slurm_acct_db.* TO 'slurm'@'localhost';
EOF
}

start_daemon() {  # start_daemon NAME COMMAND...
    local name="$1"; shift
    running "$name" && return 0
    rm -f "$STATE/run/$name.pid"
    "$@" || die "$name did not start (log $STATE/log/$name.log)"
    wait_for 30 "$name" test -s "$STATE/run/$name.pid"
    sleep 1
    kill -0 "$(cat "$STATE/run/$name.pid")" 2>/dev/null || die "$name stopped right after starting: $(tail -n 3 "$STATE/log/$name.log")"
    cp "$STATE/run/$name.pid" "$STATE/$name.pid"
}

node_idle() { sinfo -h -N -o "%t" 2>/dev/null | grep -qE "^(idle|mix|alloc)"; }

link_default_config() {
    # job steps (srun inside a batch job) look for /etc/slurm/slurm.conf whatever SLURM_CONF said at submission:
    # point it at ours, unless a site configuration is there (then refuse rather than overwrite it)
    local default=/etc/slurm/slurm.conf
    if [ -e "$default" ] && [ "$(readlink -f "$default")" != "$(readlink -f "$STATE/slurm.conf")" ]; then
        [ -L "$default" ] && grep -q "written by scripts/local_slurm.sh" "$default" 2>/dev/null \
            || die "$default exists (a site configuration?): this script will not replace it"
    fi
    mkdir -p /etc/slurm && ln -sfn "$STATE/slurm.conf" "$default"
}

start() {
    install_packages
    write_configs
    link_default_config
    export SLURM_CONF="$STATE/slurm.conf"
    start_munge
    start_database
    start_daemon slurmdbd slurmdbd  # reads slurmdbd.conf beside $SLURM_CONF
    wait_for 60 slurmdbd sacctmgr -n list cluster
    sacctmgr -i add cluster ppmlocal >/dev/null 2>&1 || true
    sacctmgr -i add account ppm Description=ppm-hrtf Organization=ppm-hrtf >/dev/null 2>&1 || true
    sacctmgr -i add user "$(id -un)" Account=ppm DefaultAccount=ppm >/dev/null 2>&1 || true
    # -c: a test cluster starts without the jobs of its last life (a job left running when it was stopped would
    # come back and end as TIMEOUT, its start long past); sacct's records of such jobs are closed as runaways
    start_daemon slurmctld slurmctld -c -f "$SLURM_CONF"
    sacctmgr -i list runawayjobs >/dev/null 2>&1 || true
    start_daemon slurmd slurmd -f "$SLURM_CONF"
    wait_for 60 "the node $HOST" node_idle
    scontrol update NodeName="$HOST" State=RESUME >/dev/null 2>&1 || true
    log "up: $(sinfo -h -N -o '%N %t %c CPUs %m MB')"
    echo "export SLURM_CONF=$SLURM_CONF"
}

stop() {
    export SLURM_CONF="$STATE/slurm.conf"
    for name in slurmd slurmctld slurmdbd mariadbd munged; do
        if running "$name"; then
            local pid; pid="$(cat "$STATE/$name.pid")"
            kill "$pid" 2>/dev/null || true
            for _ in $(seq 1 30); do kill -0 "$pid" 2>/dev/null || break; sleep 1; done
            kill -9 "$pid" 2>/dev/null || true
            log "stopped $name ($pid)"
        fi
        rm -f "$STATE/$name.pid"
    done
    if [ "$(readlink -f /etc/slurm/slurm.conf 2>/dev/null)" = "$(readlink -f "$STATE/slurm.conf")" ]; then
        rm -f /etc/slurm/slurm.conf
    fi
}

case "${1:-}" in
    start) start ;;
    stop) stop ;;
    status) if running slurmctld; then SLURM_CONF="$STATE/slurm.conf" sinfo -N; else echo stopped; fi ;;
    env) echo "export SLURM_CONF=$STATE/slurm.conf" ;;
    *) die "usage: bash scripts/local_slurm.sh start|stop|status|env" ;;
esac
