//! Thin wrapper: see [`experiments::renderings`].
use clap::Parser;

fn main() -> anyhow::Result<()> {
    let args = experiments::renderings::Args::parse();
    experiments::renderings::run(&args)?;
    Ok(())
}
