//! One module per subcommand: each has an `Args` struct (clap) and a `run` function.

pub mod eval;
pub mod features;
pub mod gen_dataset;
pub mod info;
pub mod merge;
// Until `sim::print_end` prints through `crate::output::outln!` (a closed stdout panics there).
#[allow(clippy::print_stdout)]
pub mod sim;
pub mod train;
