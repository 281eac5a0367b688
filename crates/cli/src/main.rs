//! `lgdm`: the command line of the lifelong 3D object recognition and grasping system.
//!
//! `main` only parses arguments, runs one subcommand and maps its error to an exit code;
//! every subcommand lives in its own module under `cmd/` and composes library calls. Stdout and
//! stderr are written only through [`output`], so a closed pipe ends a command quietly instead of
//! panicking.
#![deny(clippy::print_stdout, clippy::print_stderr)]
// The options' doc comments are clap's `--help` text, where `<category>/<instance>` are
// placeholders, not HTML; escaping them would show the escapes in the help.
#![allow(rustdoc::invalid_html_tags)]

mod cmd;
mod data;
#[cfg(test)]
mod docs_examples;
mod output;
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
    /// Run a lifelong-learning scenario over trials: model, metrics.json, plots, summary.
    Train(cmd::train::Args),
    /// Score a saved model on a dataset: accuracy, confusion matrix, size, inference time.
    Eval(cmd::eval::Args),
    /// Generate a sequential point-cloud dataset: MCAP collections, manifest, grasp images.
    GenDataset(cmd::gen_dataset::Args),
    /// Compute per-view features of a dataset and write them with labels as .npz.
    Features(cmd::features::Args),
    /// Combine the trials of several run directories of one experiment into one run.
    Merge(cmd::merge::Args),
    /// The tabletop robot: grasp trials in the physics simulation.
    Sim(cmd::sim::Args),
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_env("LGDM_LOG")
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")),
        )
        .with_writer(std::io::stderr)
        // Otherwise a failed write to a closed stderr is reported with `eprintln!`, which panics.
        .log_internal_errors(false)
        .init();
    let result = match cli.command {
        Command::Info => cmd::info::run(),
        Command::Train(args) => cmd::train::run(args),
        Command::Eval(args) => cmd::eval::run(args),
        Command::GenDataset(args) => cmd::gen_dataset::run(args),
        Command::Features(args) => cmd::features::run(args),
        Command::Merge(args) => cmd::merge::run(args),
        Command::Sim(args) => cmd::sim::run(args),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        // The reader of stdout has gone (`lgdm … | head`): nothing is wrong, stop quietly.
        Err(err) if output::is_stdout_closed(&err) => std::process::ExitCode::SUCCESS,
        // A robot run stopped by Ctrl-C after a whole round: the shell's code for SIGINT.
        Err(err) if err.downcast_ref::<cmd::sim::Interrupted>().is_some() => {
            output::errln!("{err:#}");
            std::process::ExitCode::from(130)
        }
        Err(err) => {
            output::errln!("error: {err:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

#[cfg(test)]
mod resume_conflicts {
    use super::Cli;
    use clap::Parser;

    /// Every option that describes a robot run is refused beside `--resume` (the run's
    /// job.json holds them): a list kept by hand once lost two of them.
    #[test]
    fn every_robot_option_conflicts_with_resume() {
        for sub in ["grasp", "pick-place", "packing"] {
            for option in [
                &["--grasp", "random"][..],
                &["--config", "x.toml"],
                &["--gripper", "2f-140"],
                &["--meshes", "m"],
                &["--draw", "mesh"],
                &["--shapes", "hull"],
                &["--record"],
                &["--record-rounds", "1"],
                &["--ae-checkpoint", "c.pt"],
                &["--seed", "3"],
            ] {
                let mut argv = vec!["lgdm", "sim", sub, "--resume", "D"];
                argv.extend_from_slice(option);
                let err = Cli::try_parse_from(&argv).expect_err(&format!("{argv:?}"));
                assert!(
                    err.to_string().contains("cannot be used with"),
                    "{argv:?}: {err}"
                );
            }
        }
    }
}
