#!/usr/bin/env bash
# End-to-end check of the Slurm recipe on one machine: a private single-node Slurm cluster on localhost
# (munged + slurmctld + slurmd, run as root, all state under DEMO_DIR), the job array of submit.sh plus its
# dependent merge job, then a byte-for-byte comparison of the merged image and film with a one-process
# render. Needs root and Debian's slurm-wlm:  apt-get update && apt-get install -y slurm-wlm
# Nothing outside DEMO_DIR is changed; the daemons are stopped on exit. Not part of CI.
#
# usage: scripts/slurm/local_demo.sh
# environment: DEMO_DIR (default /tmp/strata-slurm-demo), PARTS (4), SPP (16), PORT (16817: slurmctld;
#              slurmd uses PORT+1), STRATA (default: target/release/strata, built if missing)
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
D=${DEMO_DIR:-/tmp/strata-slurm-demo}
PARTS=${PARTS:-4}
SPP=${SPP:-16}
PORT=${PORT:-16817}

for b in munged slurmctld slurmd sbatch squeue scontrol sinfo srun; do
    command -v "$b" > /dev/null || { echo "error: $b not found: apt-get update && apt-get install -y slurm-wlm" >&2; exit 2; }
done
[ "$(id -u)" = 0 ] || { echo "error: run as root (the demo cluster's daemons run as root)" >&2; exit 2; }
if [ -z "${STRATA:-}" ]; then
    STRATA=$root/target/release/strata
    [ -x "$STRATA" ] || (cd "$root" && cargo build --release)
fi
export STRATA

rm -rf "$D"
mkdir -p "$D"/{state,spool,munge,out}
chown munge:munge "$D/munge"
chmod 0755 "$D/munge"
node=$(hostname -s)
cpus=$(nproc)

# --- munge: a private daemon on a private socket (a system munged, if any, is left alone) ---
runuser -u munge -- munged --socket="$D/munge/munge.socket" --pid-file="$D/munge/munged.pid" \
    --log-file="$D/munge/munged.log" --seed-file="$D/munge/munged.seed" --key-file=/etc/munge/munge.key

# Stop the daemons this script started (by their pid files) and wait until they are gone.
cleanup() {
    for p in "$D/slurmd.pid" "$D/slurmctld.pid" "$D/munge/munged.pid"; do
        [ -f "$p" ] || continue
        pid=$(cat "$p")
        kill "$pid" 2> /dev/null || continue
        for _ in $(seq 50); do
            state=$(awk '{print $3}' "/proc/$pid/stat" 2> /dev/null || echo gone)
            if [ "$state" = gone ] || [ "$state" = Z ]; then break; fi
            sleep 0.2
        done
    done
}
trap cleanup EXIT

# --- slurm.conf: one node (this machine), one partition, no accounting, no cgroups ---
cat > "$D/slurm.conf" << CONF
ClusterName=strata-demo
SlurmctldHost=$node(127.0.0.1)
SlurmUser=root
SlurmdUser=root
SlurmctldPort=$PORT
SlurmdPort=$((PORT + 1))
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$D/munge/munge.socket
StateSaveLocation=$D/state
SlurmdSpoolDir=$D/spool
SlurmctldPidFile=$D/slurmctld.pid
SlurmdPidFile=$D/slurmd.pid
SlurmctldLogFile=$D/slurmctld.log
SlurmdLogFile=$D/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
MpiDefault=none
ReturnToService=2
MinJobAge=600
NodeName=$node NodeAddr=127.0.0.1 CPUs=$cpus State=UNKNOWN
PartitionName=demo Nodes=$node Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF=$D/slurm.conf

slurmctld -f "$SLURM_CONF"
slurmd -f "$SLURM_CONF" -N "$node"
for _ in $(seq 60); do
    state=$(sinfo -h -o %t 2> /dev/null || true)
    [ "$state" = idle ] && break
    sleep 1
done
[ "$state" = idle ] || { echo "error: node state '$state' (see $D/slurmctld.log, $D/slurmd.log)" >&2; exit 1; }
echo "slurm: node $node idle with $cpus CPUs"

# --- the render: a small showcase, PARTS array tasks, then the merge ---
scene=$D/scene.toml
sed -e 's/^width = 640/width = 320/' -e 's/^height = 400/height = 200/' "$root/scenes/showcase.toml" > "$scene"
flags=(--profile final --seed 5)
read -r render merge <<< "$(WORKDIR=$D/out CHECKPOINT=5 "$root/scripts/slurm/submit.sh" "$PARTS" "$SPP" "$D/merged.exr" "$scene" "${flags[@]}")"
echo "submitted array job $render ($PARTS tasks) and merge job $merge (afterok:$render)"
t0=$(date +%s)
while squeue -h -j "$render,$merge" 2> /dev/null | grep -q .; do
    [ $(( $(date +%s) - t0 )) -lt 600 ] || { echo "error: jobs still queued after 600 s" >&2; squeue >&2; exit 1; }
    sleep 2
done
for j in "$render" "$merge"; do
    scontrol -o show job "$j" | while read -r line; do
        echo "  $(tr ' ' '\n' <<< "$line" | grep -E '^(JobId|ArrayTaskId|JobName|JobState|ExitCode)=' | paste -sd' ' -)"
    done
done
if scontrol show job "$merge" | grep -q 'JobState=COMPLETED'; then :; else
    echo "error: the merge job did not complete; logs:" >&2
    tail -n 20 "$D"/out/*.log >&2 || true
    exit 1
fi
echo "--- merge log ---"
cat "$D"/out/strata-merge-"$merge".log

# --- ground truth: one process, same scene, seed and profile ---
"$STRATA" render "$scene" --spp "$SPP" "${flags[@]}" -q -o "$D/single.exr" --film "$D/single.film"
cmp "$D/merged.exr" "$D/single.exr"
cmp "$D/out/merged.film" "$D/single.film"
echo "OK: the Slurm merge of $PARTS sample ranges equals the one-process render byte for byte" \
    "($(stat -c %s "$D/merged.exr") bytes of EXR, $(stat -c %s "$D/single.film") bytes of film)"
