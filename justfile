# Everyday recipes (https://github.com/casey/just). Each is one cargo command; no just needed to run them by hand.

# Regenerate every figure and results/README.md (full size; about 8.5 min on 2 cores)
figures:
    cargo run --release -p experiments --bin figures

# Every experiment CI-sized, into /tmp/scatterbench-quick
figures-quick:
    cargo run --release -p experiments --bin figures -- --quick --out /tmp/scatterbench-quick

# All tests (the command CI runs)
test:
    cargo test --workspace --release

# Criterion benchmarks with the bandwidth probe; writes results/bench/
bench:
    cargo bench -p benches

# Formatting and lints as CI checks them
lint:
    cargo fmt --all -- --check
    cargo clippy --workspace --all-targets -- -D warnings
