#!/usr/bin/env bash
# A real Slurm cluster in the tests: a one-node cluster on localhost (munged, slurmctld, slurmd,
# every file in a temporary folder) runs a planned weather sweep (2 worlds x 2 conditions, scale
# 0.2, 4 s of route each) and a 4-shard map build (NAIP 2009) as job arrays, each with the merge
# the array queues; the merged outputs must equal single-process runs:
#   - weather: table.md and table.csv byte for byte once the run records carry the single run's
#     timing (fps, wall time: the only figures two runs cannot share); results.json the same but
#     for `reused` and the total wall time;
#   - map: the merged database byte for byte (so the same tiles and features), `map info --check`
#     passes, and `map locate` gives the same fixes for the same frames.
# Every daemon it starts is stopped by its pid on exit, whatever happens (jobs cancelled first);
# the last check is that none is left. Run as root (the daemons run as root here).
#   scripts/slurm_test.sh [BUILD_DIR]        (default build/; $OPTINAV_SLURM_TIMEOUT s, 600)
# Installs slurm-wlm and munge with apt-get when missing (services not started).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD="$(cd "${1:-${ROOT}/build}" && pwd)"
OPTINAV="${BUILD}/optinav"
DATA="$(cd "${OPTINAV_SHARED_DATA:-${ROOT}/../shared/data}" && pwd -P)"  # absolute, as plans write it
TIMEOUT="${OPTINAV_SLURM_TIMEOUT:-600}"
PY=/usr/bin/python3
START=$(date +%s)
say() { echo "slurm_test: $*"; }
fail() { echo "slurm_test: FAIL: $*" >&2; exit 1; }
[[ -x "${OPTINAV}" ]] || fail "no ${OPTINAV} (build first)"
[[ "$(id -u)" == 0 ]] || fail "run as root (slurmd and munged run as root in this test)"

# --- packages -------------------------------------------------------------------------------
missing=()
for pkg in slurm-wlm munge; do
  dpkg-query -W -f='${Status}' "${pkg}" 2>/dev/null | grep -q "install ok installed" ||
    missing+=("${pkg}")
done
if ((${#missing[@]})); then
  say "installing ${missing[*]}"
  # The packages' services must not start: this test runs its own daemons.
  policy_added=0
  if [[ ! -e /usr/sbin/policy-rc.d ]]; then
    printf '#!/bin/sh\nexit 101\n' > /usr/sbin/policy-rc.d
    chmod +x /usr/sbin/policy-rc.d
    policy_added=1
  fi
  DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends "${missing[@]}" \
    || { ((policy_added)) && rm -f /usr/sbin/policy-rc.d; fail "apt-get install ${missing[*]}"; }
  ((policy_added)) && rm -f /usr/sbin/policy-rc.d
fi

# --- the cluster ----------------------------------------------------------------------------
T="$(mktemp -d /tmp/optinav_slurm.XXXXXX)"
chmod 755 "${T}"
export SLURM_CONF="${T}/slurm.conf"
PIDFILES=("${T}/slurmd.pid" "${T}/slurmctld.pid" "${T}/munge/munged.pid")

stop_all() {
  local rc=$?
  set +e
  if [[ -f "${T}/slurmctld.pid" ]]; then
    scancel --quiet --full --user=root 2>/dev/null
    for _ in $(seq 30); do
      [[ -z "$(squeue -h 2>/dev/null)" ]] && break
      sleep 1
    done
  fi
  for f in "${PIDFILES[@]}"; do
    [[ -f "${f}" ]] || continue
    pid=$(cat "${f}")
    kill "${pid}" 2>/dev/null
    for _ in $(seq 50); do kill -0 "${pid}" 2>/dev/null || break; sleep 0.2; done
    kill -0 "${pid}" 2>/dev/null && kill -9 "${pid}" 2>/dev/null
  done
  left=""
  for f in "${PIDFILES[@]}"; do
    [[ -f "${f}" ]] && kill -0 "$(cat "${f}")" 2>/dev/null && left+=" $(cat "${f}")"
  done
  left+=" $(pgrep -f "${T}" | tr '\n' ' ')"
  left+=" $(pgrep -x slurmstepd | tr '\n' ' ')"
  if [[ -n "${left// /}" ]]; then
    echo "slurm_test: FAIL: processes left running:${left}" >&2
    rc=1
  else
    say "every daemon stopped (pgrep: none left)"
  fi
  if ((rc)) && [[ -d "${T}/log" ]]; then
    for f in "${T}"/log/*.log; do echo "--- ${f} (last lines)"; tail -15 "${f}"; done >&2
  fi
  [[ "${KEEP_SLURM_TEST:-0}" == 1 ]] && say "kept ${T}" || rm -rf "${T}"
  say "$( ((rc)) && echo FAILED || echo passed) in $(($(date +%s) - START)) s"
  exit "${rc}"
}
trap stop_all EXIT
trap 'exit 130' INT TERM

free_port() {
  local p
  while :; do
    p=$((20000 + RANDOM % 20000))
    ss -ltn 2>/dev/null | grep -q ":${p} " || { echo "${p}"; return; }
  done
}
mkdir -p "${T}/munge" "${T}/state" "${T}/spool" "${T}/log"
chmod 700 "${T}/munge"
mungekey --create --keyfile="${T}/munge/munge.key" --force
chmod 600 "${T}/munge/munge.key"
munged --force --socket="${T}/munge/munge.socket" --key-file="${T}/munge/munge.key" \
  --pid-file="${T}/munge/munged.pid" --log-file="${T}/log/munged.log" \
  --seed-file="${T}/munge/munged.seed"
HOST="$(hostname -s)"
MEM_MB=$(awk '/MemTotal/ {print int($2 / 1024 * 0.9)}' /proc/meminfo)
CTLD_PORT=$(free_port)
SLURMD_PORT=$(free_port)
cat > "${SLURM_CONF}" <<CONF
ClusterName=optinavtest
SlurmctldHost=${HOST}(127.0.0.1)
SlurmctldPort=${CTLD_PORT}
SlurmdPort=${SLURMD_PORT}
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=${T}/munge/munge.socket
SlurmUser=root
SlurmdUser=root
StateSaveLocation=${T}/state
SlurmdSpoolDir=${T}/spool
SlurmctldPidFile=${T}/slurmctld.pid
SlurmdPidFile=${T}/slurmd.pid
SlurmctldLogFile=${T}/log/slurmctld.log
SlurmdLogFile=${T}/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
SchedulerType=sched/backfill
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MpiDefault=none
ReturnToService=2
InactiveLimit=0
KillWait=5
MinJobAge=600
NodeName=${HOST} NodeAddr=127.0.0.1 CPUs=2 RealMemory=${MEM_MB} State=UNKNOWN
PartitionName=debug Nodes=ALL Default=YES MaxTime=INFINITE State=UP
CONF
slurmctld -f "${SLURM_CONF}"
slurmd -f "${SLURM_CONF}"
for _ in $(seq 30); do
  sinfo -h -o %T 2>/dev/null | grep -q idle && break
  sleep 1
done
sinfo -h -o %T | grep -q idle || fail "the node did not come up (sinfo: $(sinfo -h 2>&1))"
say "cluster up: ${HOST}, 2 CPUs, ${MEM_MB} MB (SLURM_CONF=${SLURM_CONF})"

# --- the work -------------------------------------------------------------------------------
# Scale 0.2 (160x120): at 0.1 (80x60) the odometry never initialises and every row is "failed".
WEATHER=(--worlds urban,terrain --conditions none,fog:50 --scale 0.2 --duration 4)
NAIP="${DATA}/geo/naip/naip_20090818.tif"
MAP=(--ortho "${NAIP}" --altitude 640 --hfov 90 --frame-size 256x256 --threads 2)
"${OPTINAV}" bench weather --out "${T}/sweep" "${WEATHER[@]}" --plan slurm
"${OPTINAV}" map build "${MAP[@]}" --out "${T}/map.db" --plan slurm --shards 4
WJOB=$(sbatch --parsable "${T}/sweep/submit.sbatch")
MJOB=$(sbatch --parsable "${T}/map.db.slurm/submit.sbatch")
say "submitted the sweep (job ${WJOB}, $(grep -c '"index"' "${T}/sweep/plan.json") tasks) and the map build (job ${MJOB}, 4 shards)"

# Single-process references while the cluster works (one core each, as the jobs share two).
"${OPTINAV}" bench weather --out "${T}/single" "${WEATHER[@]}" > "${T}/single_weather.log"
"${OPTINAV}" map build "${MAP[@]}" --out "${T}/single.db" > "${T}/single_map.log"
say "single-process runs done"

deadline=$((START + TIMEOUT))
until [[ -f "${T}/sweep/table.md" && -f "${T}/map.db" && -z "$(squeue -h)" ]]; do
  if (($(date +%s) > deadline)); then
    squeue >&2
    for f in "${T}"/sweep/logs/*.log "${T}"/map.db.slurm/logs/*.log; do
      [[ -f "$f" ]] && { echo "--- $f"; tail -5 "$f"; } >&2
    done
    fail "timeout (${TIMEOUT} s) waiting for the jobs"
  fi
  sleep 2
done
say "jobs done: merges wrote ${T}/sweep/table.md and ${T}/map.db"
grep -q "merged" "${T}/map.db.slurm/logs/merge.log" || fail "the map merge job did not log"

# --- compare: weather -------------------------------------------------------------------------
# The runs' timing is what two runs cannot share: give the sweep's run records the single run's
# and merge again by hand; every byte of the tables must then agree.
"${PY}" - "${T}/single/runs" "${T}/sweep/runs" <<'PYEOF'
import json, pathlib, sys
single, sweep = map(pathlib.Path, sys.argv[1:3])
records = sorted(p.name for p in single.glob("*.json") if not p.name.endswith(".stats.json"))
assert records and records == sorted(
    p.name for p in sweep.glob("*.json") if not p.name.endswith(".stats.json")), "different runs"
for name in records:
    s = json.loads((single / name).read_text())
    w = json.loads((sweep / name).read_text())
    for key in ("wall_s", "fps", "frame_median_ms", "frame_p95_ms"):
        w[key] = s[key]
    (sweep / name).write_text(json.dumps(w, indent=2) + "\n")
print(f"slurm_test: timing of {len(records)} runs taken from the single-process run")
PYEOF
"${OPTINAV}" bench weather --out "${T}/sweep" --reuse > "${T}/merge_again.log"
for f in table.md table.csv; do
  cmp "${T}/single/${f}" "${T}/sweep/${f}" || fail "weather ${f} differs"
done
"${PY}" - "${T}/single/results.json" "${T}/sweep/results.json" <<'PYEOF'
import json, sys
a, b = (json.load(open(p)) for p in sys.argv[1:3])
for j in (a, b):
    j.pop("wall_s")
    for r in j["runs"]:
        r.pop("reused")
assert a == b, "results.json differs"
PYEOF
say "weather: table.md, table.csv identical; results.json identical but for reused/wall_s"

# --- compare: map -----------------------------------------------------------------------------
cmp "${T}/single.db" "${T}/map.db" || fail "the merged map differs from the single build"
"${OPTINAV}" map info "${T}/map.db" --check | grep -Eq "check *: ok" || fail "map info --check"
"${OPTINAV}" map render --ortho "${DATA}/geo/naip/naip_20120731.tif" --set 6 --seed 3 \
  --frame-size 256x256 --altitude 640 --hfov 90 --out-dir "${T}/frames" > /dev/null
for db in single.db map.db; do
  "${OPTINAV}" map locate --map "${T}/${db}" --images-from "${T}/frames/frames.csv" |
    "${PY}" -c 'import json, sys
for line in sys.stdin:
    j = json.loads(line)
    for k in ("time_ms", "times_ms"):
        j.pop(k, None)
    print(json.dumps(j, sort_keys=True))' > "${T}/locate_${db}.jsonl"
done
[[ -s "${T}/locate_single.db.jsonl" ]] || fail "no locate output"
cmp "${T}/locate_single.db.jsonl" "${T}/locate_map.db.jsonl" || fail "locate results differ"
say "map: merged database identical, --check ok, $(grep -c '"localized": true' \
  "${T}/locate_map.db.jsonl")/6 frames located identically"
