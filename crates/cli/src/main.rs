//! `lgdm`: the command line of the lifelong 3D object recognition and grasping system.
//!
//! `main` only parses arguments, runs one subcommand and maps its error to an exit code;
//! every subcommand lives in its own module under `cmd/` and composes library calls.

mod cmd;
#[allow(dead_code)] // used by the subcommands as they land
mod progress;

use clap::{Parser, Subcommand};

/// Lifelong 3D object recognition and grasp synthesis.
#[derive(Debug, Parser)]
#[command(name = "lgdm", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Print the build's version and the embedded defaults.
    Info,
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_env("LGDM_LOG")
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")),
        )
        .with_writer(std::io::stderr)
        .init();
    let result = match cli.command {
        Command::Info => cmd::info::run(),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {err:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
