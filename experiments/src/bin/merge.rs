//! Binary of [`experiments::shard::merge`]: joins the shards of a `--shard i/N` run.
fn main() -> anyhow::Result<()> {
    use clap::Parser as _;
    experiments::shard::merge(&experiments::shard::MergeArgs::parse())
}
