//! `lgdm info`: version and build facts.

/// Prints the version of the binary.
pub fn run() -> anyhow::Result<()> {
    println!("lgdm {}", env!("CARGO_PKG_VERSION"));
    Ok(())
}
