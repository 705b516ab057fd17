//! Thin wrapper: see [`experiments::pt_slab`].
use clap::Parser;

fn main() -> anyhow::Result<()> {
    let args = experiments::pt_slab::Args::parse();
    experiments::pt_slab::run(&args)?;
    Ok(())
}
