//! Thin wrapper: see [`experiments::point_source`].
use clap::Parser;

fn main() -> anyhow::Result<()> {
    let args = experiments::point_source::Args::parse();
    experiments::point_source::run(&args)?;
    Ok(())
}
