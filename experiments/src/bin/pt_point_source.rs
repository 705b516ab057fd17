//! Thin wrapper: see [`experiments::pt_point_source`].
use clap::Parser;

fn main() -> anyhow::Result<()> {
    let args = experiments::pt_point_source::Args::parse();
    experiments::pt_point_source::run(&args)?;
    Ok(())
}
