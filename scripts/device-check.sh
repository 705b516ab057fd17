#!/usr/bin/env bash
# The prepared run for a real GPU (issue 15 acceptance 7, issue 17 acceptance 3): the GPU tests
# with the adapter required, the GPU benches, and multigrid vs SOR time-to-solution at 255³
# and 511³ (f32). Everything it writes goes under $OUT (default ./device-out): logs, the bench
# CSVs and results/multigrid_scaling_gpu. Each step has its own time limit, so one slow step
# cannot eat the others' time; a step that fails is logged and the script goes on.
#
#   OUT=/some/dir bash scripts/device-check.sh [--skip-build]
#
# Budget (measured nowhere yet; the limits are the plan): build 240 s, tests 120 s, benches
# 120 s, multigrid_scaling 200 s.
set -u
OUT=${OUT:-device-out}
mkdir -p "$OUT"
log() { echo "== $(date -u +%T) $*" | tee -a "$OUT/steps.log"; }
step() {
    local name=$1 limit=$2
    shift 2
    log "$name (limit ${limit}s): $*"
    local t0=$SECONDS
    timeout "$limit" "$@" >"$OUT/$name.log" 2>&1
    local rc=$?
    log "$name: exit $rc after $((SECONDS - t0)) s"
    tail -n 40 "$OUT/$name.log"
}

nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv >"$OUT/gpu.txt" 2>&1
lscpu >"$OUT/cpu.txt" 2>&1
export SCATTERBENCH_REQUIRE_GPU=1
if [ "${1:-}" != "--skip-build" ]; then
    step build 240 cargo build --release -p solvers -p benches -p experiments --tests --benches --bins
fi
step gpu-tests 120 cargo test --release -p solvers --test integration -- fld_multigrid_gpu:: \
    pop_gpu:: conformance:: --test-threads 1
step bench-diffusion-gpu 60 cargo bench -p benches --bench diffusion_gpu
step bench-pop 60 cargo bench -p benches --bench pop -- gpu
cp -r results/bench "$OUT/bench" 2>/dev/null
step multigrid-gpu 200 cargo run --release -p experiments --bin multigrid_scaling -- \
    --backend gpu --n 255,511 --sor-max-n 255 --problems point_source --tolerance 1e-5 \
    --no-progress --out "$OUT/multigrid_scaling_gpu"
log done
