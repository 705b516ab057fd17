//! Thin wrapper: see [`experiments::point_source_analytic`].
use clap::Parser;

fn main() -> anyhow::Result<()> {
    let args = experiments::point_source_analytic::Args::parse();
    experiments::point_source_analytic::run(&args)?;
    Ok(())
}
