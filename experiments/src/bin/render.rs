//! Binary of [`experiments::render`] (a tool, not one of the figures: it is not in the registry).
fn main() -> anyhow::Result<()> {
    experiments::render::main()
}
