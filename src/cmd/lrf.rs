//! `odocal lrf` subcommands (not yet available).

/// Subcommands.
#[derive(clap::Subcommand)]
pub enum Command {
    /// Placeholder until the subcommands land.
    Todo,
}

/// Runs a subcommand.
pub fn run(_cmd: Command) -> anyhow::Result<()> {
    anyhow::bail!("this command is not available yet")
}
