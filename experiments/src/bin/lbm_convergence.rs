//! Thin wrapper: see [`experiments::lbm_convergence`].
use clap::Parser;

fn main() -> anyhow::Result<()> {
    let args = experiments::lbm_convergence::Args::parse();
    experiments::lbm_convergence::run(&args)?;
    Ok(())
}
