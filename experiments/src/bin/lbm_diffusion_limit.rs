//! Thin wrapper: see [`experiments::lbm_diffusion_limit`].
use clap::Parser;

fn main() -> anyhow::Result<()> {
    let args = experiments::lbm_diffusion_limit::Args::parse();
    experiments::lbm_diffusion_limit::run(&args)?;
    Ok(())
}
