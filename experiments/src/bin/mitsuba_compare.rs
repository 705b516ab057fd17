//! Thin wrapper: see [`experiments::mitsuba_compare`].
use clap::Parser;

fn main() -> anyhow::Result<()> {
    let args = experiments::mitsuba_compare::Args::parse();
    experiments::mitsuba_compare::run(&args)?;
    Ok(())
}
