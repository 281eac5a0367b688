//! One module per subcommand: each has an `Args` struct (clap) and a `run` function.

pub mod eval;
pub mod features;
pub mod gen_dataset;
pub mod info;
pub mod merge;
pub mod sim;
pub mod train;
