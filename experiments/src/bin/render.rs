//! Thin wrapper: see [`experiments::render`].
use clap::Parser;

fn main() -> anyhow::Result<()> {
    let args = experiments::render::Args::parse();
    experiments::render::run(&args)?;
    Ok(())
}
