#!/usr/bin/env bash
# One call of a leased GPU (the `device` tool; CI never has one): what the machine has, the
# single-mesh figures of bench_gpu.py (every structure, checked against the CPU backend) and the
# packed batches of bench_batch.py, each under a hard time limit so the call ends inside its own.
#
#   OUT=/tmp/gpu bash benchmarks/gpu_lease.sh                        # the leased run (5M vertices)
#   V=20000 Q=100000 MESHES=20 OUT=/tmp/gpu bash benchmarks/gpu_lease.sh   # a smoke run on CPU
#   MATCH=1 BATCH=0 STRUCTURES=pemb ... : also race pemb's matches searched vs sorted
#     (benchmarks/race_pemb_match.py; MATCH_V vertices, MATCH_MESHES meshes, T3 seconds)
#
# Runs from the repository root with the machine's own python3 (jax there may be newer than the
# range pyproject.toml pins: the versions are printed first and kept in env.txt).
set -u
OUT=${OUT:-benchmarks/out/gpu}
V=${V:-5000000}; Q=${Q:-10000000}; MESHES=${MESHES:-1000}
T1=${T1:-330}; DEADLINE=${DEADLINE:-250}; T2=${T2:-200}
PY=${PY:-python3}; STRUCTURES=${STRUCTURES:-halfedge,corner-table,cds5n-o1,cds6n,lr,pemb,cds5n,cds4n,lr-bits}
BATCH=${BATCH:-1}
mkdir -p "$OUT"
export PYTHONPATH=$PWD PYTHONUNBUFFERED=1
{
  date -u; uname -a; nproc; free -g | head -2
  nvidia-smi --query-gpu=name,memory.total,driver_version,clocks.sm,clocks.max.sm --format=csv 2>&1
  $PY -c "import jax, numba, numpy, scipy; print('jax', jax.__version__, jax.devices(), 'numba', numba.__version__, 'numpy', numpy.__version__, 'scipy', scipy.__version__)" 2>&1
} > "$OUT/env.txt"
cat "$OUT/env.txt"
t0=$(date +%s)
timeout "$T1" $PY benchmarks/bench_gpu.py --vertices "$V" --queries "$Q" --deadline "$DEADLINE" \
  --structures "$STRUCTURES" --repeats 5 --out "$OUT" 2> "$OUT/bench_gpu.log"
echo "bench_gpu rc=$? in $(( $(date +%s) - t0 )) s"
grep -E "Error|skipped" "$OUT/bench_gpu.log" | cut -c1-300 | head -20
if [ "${MATCH:-0}" = 1 ]; then  # pemb's matches searched vs sorted (bp.MATCH_BY_SORT), single and packed
  t0=$(date +%s)
  timeout "${T3:-180}" $PY benchmarks/race_pemb_match.py --vertices "${MATCH_V:-1000000}" \
    --meshes "${MATCH_MESHES:-300}" --rounds 5 --json "$OUT/race_pemb_match.json" > "$OUT/race_pemb_match.log" 2>&1
  echo "race_pemb_match rc=$? in $(( $(date +%s) - t0 )) s"; tail -12 "$OUT/race_pemb_match.log"
fi
[ "$BATCH" = 1 ] || exit 0
t0=$(date +%s)
timeout "$T2" $PY benchmarks/bench_batch.py --meshes "$MESHES" --no-check \
  --structures cds5n-o1,lr,pemb,cds6n,cds5n,cds4n,lr-bits --loop-meshes 5 --queries 1000000 \
  --repeat 7 --json "$OUT/bench_batch_gpu.json" > "$OUT/bench_batch.log" 2>&1
echo "bench_batch rc=$? in $(( $(date +%s) - t0 )) s"
grep -v '^{' "$OUT/bench_batch.log" | cut -c1-200 | tail -45
