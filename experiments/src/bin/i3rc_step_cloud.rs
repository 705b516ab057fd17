//! Thin wrapper: see [`experiments::i3rc_step_cloud`].
use clap::Parser;

fn main() -> anyhow::Result<()> {
    let args = experiments::i3rc_step_cloud::Args::parse();
    experiments::i3rc_step_cloud::run(&args)?;
    Ok(())
}
