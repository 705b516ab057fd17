//! Thin wrapper: see [`experiments::transport_references`].
use clap::Parser;

fn main() -> anyhow::Result<()> {
    let args = experiments::transport_references::Args::parse();
    experiments::transport_references::run(&args)?;
    Ok(())
}
