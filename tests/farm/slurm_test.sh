#!/usr/bin/env bash
# End to end on a real Slurm: a single-node cluster (munged, slurmctld, slurmd on this machine, state in a temp
# folder) runs `residue-cli farm slurm` on a 48-frame sequence as a job array of 6 chunks. One frame is broken:
# its chunk fails, is retried, and the gather job reports it (exit 3). The frame is mended and the job
# resubmitted: only the missing frame is denoised, the 47 finished ones are skipped, and the summary is clean.
# Usage: slurm_test.sh RESIDUE_CLI EXAMPLE_DIR. Exit 77 (ctest: skipped) when Slurm or munge is missing or cannot
# start here (not root, no munge key).
set -euo pipefail
cli=$1 example=$2
skip() { echo "SKIP: $*"; exit 77; }
for tool in munged slurmctld slurmd sbatch squeue sinfo; do
  command -v "$tool" >/dev/null || [ -x "/usr/sbin/$tool" ] || skip "$tool is not installed (apt-get install slurm-wlm munge)"
done
[ "$(id -u)" -eq 0 ] || skip "a local slurmd must run as root"
[ -r /etc/munge/munge.key ] || skip "no munge key in /etc/munge"

work=$(mktemp -d /tmp/residue-slurm-XXXXXX)
chmod 755 "$work"
cluster=$work/cluster
mkdir -p "$cluster"/{state,spool,munge,log}
stop() {
  set +e
  [ -n "${SLURM_CONF:-}" ] && scancel --quiet -u root 2>/dev/null
  for pid in "$cluster"/slurmd.pid "$cluster"/slurmctld.pid "$cluster"/munge/munged.pid; do
    [ -s "$pid" ] && kill "$(cat "$pid")" 2>/dev/null
  done
  sleep 0.5
  rm -rf "$work"
}
trap stop EXIT

# munge, as the munge user, on its own socket.
chown munge:munge "$cluster/munge"
touch "$cluster/log/munged.log" && chown munge:munge "$cluster/log/munged.log"
runuser -u munge -- /usr/sbin/munged --socket="$cluster/munge/munge.socket" --pid-file="$cluster/munge/munged.pid" \
  --log-file="$cluster/log/munged.log" --seed-file="$cluster/munge/seed" --key-file=/etc/munge/munge.key ||
  skip "munged does not start: $(tail -3 "$cluster/log/munged.log")"

port=$((20000 + $$ % 20000))
host=$(hostname -s)
cat >"$cluster/slurm.conf" <<CONF
ClusterName=residue-test
SlurmctldHost=$host
AuthType=auth/munge
AuthInfo=socket=$cluster/munge/munge.socket
SlurmUser=root
SlurmdUser=root
StateSaveLocation=$cluster/state
SlurmdSpoolDir=$cluster/spool
SlurmctldPidFile=$cluster/slurmctld.pid
SlurmdPidFile=$cluster/slurmd.pid
SlurmctldLogFile=$cluster/log/slurmctld.log
SlurmdLogFile=$cluster/log/slurmd.log
SlurmctldPort=$port
SlurmdPort=$((port + 1))
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
MpiDefault=none
JobAcctGatherType=jobacct_gather/none
NodeName=$host CPUs=$(nproc) RealMemory=1000 State=UNKNOWN
PartitionName=test Nodes=ALL Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF=$cluster/slurm.conf
/usr/sbin/slurmctld -f "$SLURM_CONF" || skip "slurmctld does not start: $(tail -3 "$cluster/log/slurmctld.log")"
/usr/sbin/slurmd -f "$SLURM_CONF" || skip "slurmd does not start: $(tail -3 "$cluster/log/slurmd.log")"
for _ in $(seq 1 60); do sinfo -h -o %T 2>/dev/null | grep -qE "idle|mixed" && break; sleep 0.5; done
sinfo -h -o %T | grep -qE "idle|mixed" || skip "the node did not come up: $(tail -3 "$cluster/log/slurmd.log")"
echo "cluster up: $(sinfo -h -o '%P %D %T %C')"

# 48 frames (the bundled room, each frame its own file) with references; frame 1020 broken.
seq_dir=$work/shot
mkdir -p "$seq_dir" "$work/out"
for f in $(seq 1001 1048); do
  cp "$example/noisy.exr" "$seq_dir/shot.$f.exr"
  cp "$example/reference.exr" "$seq_dir/ref.$f.exr"
done
echo "not an EXR" >"$seq_dir/shot.1020.exr"

wait_for_jobs() {
  for _ in $(seq 1 600); do
    [ -z "$(squeue -h -o %i)" ] && return 0
    sleep 0.5
  done
  echo "FAIL: jobs still queued after 300 s"; squeue; exit 1
}
summary_field() { /usr/bin/python3 -c "import json,sys; print(json.load(open(sys.argv[1]))[sys.argv[2]])" "$1" "$2"; }
expect() { [ "$2" = "$3" ] || { echo "FAIL: $1: expected $3, got $2"; exit 1; }; }

"$cli" farm slurm "$seq_dir/shot.####.exr" -r "$seq_dir/ref.####.exr" -o "$work/out/den.####.exr" -m tiny \
  --chunk 8 --retries 2 --cpus-per-task 1 --job-dir "$work/job" 2>&1 | tee "$work/submit1.log"
wait_for_jobs
cat "$work/job/logs/gather.log"
expect "chunks" "$(summary_field "$work/job/summary.json" chunks)" 6
# A retried chunk's summary is its last attempt's: frames the first attempt finished count as skipped there.
ok=$(( $(summary_field "$work/job/summary.json" done) + $(summary_field "$work/job/summary.json" skipped) ))
expect "done or skipped (first run)" "$ok" 47
expect "failed (first run)" "$(summary_field "$work/job/summary.json" failed)" 1
expect "exit code (first run)" "$(summary_field "$work/job/summary.json" exit_code)" 3
attempts=$(grep -c "attempt .* failed with exit 3" "$work/job/logs/chunk_2.log" || true)
expect "attempts of the broken chunk (1 + 2 retries)" "$attempts" 3
ls "$work/out" | grep -c '^den\.' | { read -r n; expect "outputs after the first run" "$n" 47; }
stat -c %Y "$work/out/den.1001.exr" >"$work/mtime"

# Mend the frame, resubmit the same job: only frame 1020 runs.
cp "$example/noisy.exr" "$seq_dir/shot.1020.exr"
rm -f "$work/job"/chunk_*.json "$work/job/summary.json"
"$cli" farm slurm "$seq_dir/shot.####.exr" -r "$seq_dir/ref.####.exr" -o "$work/out/den.####.exr" -m tiny \
  --chunk 8 --retries 2 --cpus-per-task 1 --job-dir "$work/job" 2>&1 | tee "$work/submit2.log"
wait_for_jobs
cat "$work/job/logs/gather.log"
expect "done (rerun)" "$(summary_field "$work/job/summary.json" done)" 1
expect "skipped (rerun)" "$(summary_field "$work/job/summary.json" skipped)" 47
expect "exit code (rerun)" "$(summary_field "$work/job/summary.json" exit_code)" 0
expect "frame 1001 untouched" "$(stat -c %Y "$work/out/den.1001.exr")" "$(cat "$work/mtime")"
ls "$work/out" | grep -c '^den\.' | { read -r n; expect "outputs" "$n" 48; }
/usr/bin/python3 - "$work/job/summary.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
f = [x for x in s["frames"] if x["status"] == "done"][0]
assert f["frame"] == 1020 and f["relmse"] < f["noisy_relmse"] / 4, f
print("frame 1020: relMSE %.5f (noisy %.5f)" % (f["relmse"], f["noisy_relmse"]))
PY
echo "PASS: 48 frames in 6 chunks on Slurm; a failing chunk retried twice and reported; the rerun did only the missing frame"
