# Everyday recipes (https://github.com/casey/just). Each is one cargo command; no just needed to run them by hand.

# Regenerate every figure and results/README.md (full size; about 70 min on 2 cores: 4068 s on a 2-vCPU AMD EPYC, 2026-12-07)
figures:
    cargo run --release -p experiments --bin figures

# Every experiment CI-sized, into /tmp/scatterbench-quick
figures-quick:
    cargo run --release -p experiments --bin figures -- --quick --out /tmp/scatterbench-quick

# Re-render results/README.md from the committed results without running anything (seconds)
figures-report:
    cargo run --release -p experiments --bin figures -- --report-only

# All tests (the command CI runs)
test:
    cargo test --workspace --release

# Python venv with Mitsuba 3 (.venv-mitsuba/), the independent reference renderer
mitsuba-setup:
    bash scripts/setup-mitsuba.sh

# Our path tracer vs Mitsuba 3 (scalar_rgb and llvm_ad_rgb) on the committed comparison scenes,
# paths/s of both and their ratio (needs mitsuba-setup)
mitsuba-compare:
    for s in cloud_directional emissive_sphere dense_half_space dense_voxel environment_sphere; do \
        cargo run --release -p experiments --bin mitsuba_compare -- --scene scenes/$s.toml --variant scalar_rgb,llvm_ad_rgb; \
    done

# GPU benchmark (wgpu; set WGPU_ADAPTER_NAME to pick an adapter); writes results/bench/diffusion_gpu.csv
bench-gpu:
    cargo bench -p benches --bench diffusion_gpu

# Lattice-Boltzmann step, CPU f32/f64 and GPU, with the bandwidth probes; writes results/bench/lbm.csv
bench-lbm:
    cargo bench -p benches --bench lbm

# Criterion benchmarks with the bandwidth probe; writes results/bench/
bench:
    cargo bench -p benches

# A path-traced reference as a Slurm job array of SHARDS shards plus a merge job (see slurm/ and
# README "Running on a cluster"); e.g. just cluster-reference scenes/nebula.toml 4096 64
cluster-reference scene spp="4096" shards="16":
    cargo build --release -p experiments
    slurm/submit --shards {{shards}} --work results-cluster/render-work --out results-cluster/render -- render --scene {{scene}} --method pt --spp {{spp}}

# The accuracy atlas on Slurm: its Monte Carlo (references, path-tracer points) as SHARDS
# shards, then a merge job that runs the grid methods and writes results-cluster/accuracy_cost
cluster-atlas shards="16":
    cargo build --release -p experiments
    slurm/submit --shards {{shards}} --work results-cluster/accuracy_cost-work --out results-cluster/accuracy_cost -- accuracy_cost

# Formatting and lints as CI checks them
lint:
    cargo fmt --all -- --check
    cargo clippy --workspace --all-targets -- -D warnings
