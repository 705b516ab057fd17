//! Thin wrapper: see [`experiments::convergence`].
use clap::Parser;

fn main() -> anyhow::Result<()> {
    let args = experiments::convergence::Args::parse();
    experiments::convergence::run(&args)?;
    Ok(())
}
