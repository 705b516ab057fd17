//! Thin wrapper: see [`experiments::accuracy_cost`].
use clap::Parser;

fn main() -> anyhow::Result<()> {
    let args = experiments::accuracy_cost::Args::parse();
    experiments::accuracy_cost::run(&args)?;
    Ok(())
}
