//! Thin wrapper: see [`experiments::pt_render`].
use clap::Parser;

fn main() -> anyhow::Result<()> {
    let args = experiments::pt_render::Args::parse();
    experiments::pt_render::run(&args)?;
    Ok(())
}
