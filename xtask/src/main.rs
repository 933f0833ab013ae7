//! `cargo xtask`: the project's command line (tasks are added as their crates land).

use clap::Parser;

/// Multiple Homography Image view synthesis: tasks of the project.
#[derive(Parser, Debug)]
#[command(name = "cargo xtask", version, about)]
struct Cli {}

fn main() -> anyhow::Result<()> {
    let Cli {} = Cli::parse();
    anyhow::bail!("no task is implemented yet; see README.md for what works today")
}
