//! The binary's only writers of stdout and stderr, so that a closed pipe never panics
//! (`println!` and `eprintln!` do).
//!
//! - [`outln!`]: a line on stdout. When the reader has gone (`lgdm info | head -1`), it returns
//!   [`StdoutClosed`]; the command stops there with `?` and `main` ends quietly with exit 0, as
//!   ripgrep does. Commands print at the end, once their files are written, so stopping early
//!   loses only the rest of the printout. Any other write error is an error naming stdout.
//! - [`errln!`]: a line on stderr (notes, JSON-lines progress, the final error). A closed stderr
//!   drops it: a progress reader that went away is no reason to stop a run.
//!
//! `main` denies `clippy::print_stdout` and `clippy::print_stderr`, so the print macros cannot
//! come back.
//!
//! ```ignore
//! use crate::output::outln;
//! outln!("run directory: {}", out.display())?;
//! ```

use std::fmt;
use std::io::{ErrorKind, Write};

/// Stdout was closed by its reader (a broken pipe): the command stops quietly.
#[derive(Debug)]
pub struct StdoutClosed;

impl fmt::Display for StdoutClosed {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("stdout was closed")
    }
}

impl std::error::Error for StdoutClosed {}

/// Whether `err` (or one of its causes) is [`StdoutClosed`].
pub fn is_stdout_closed(err: &anyhow::Error) -> bool {
    err.chain().any(|cause| cause.is::<StdoutClosed>())
}

/// Writes `args` and a newline to stdout (what [`outln!`] expands to).
pub fn stdout_line(args: fmt::Arguments<'_>) -> anyhow::Result<()> {
    let mut out = std::io::stdout().lock();
    match writeln!(out, "{args}") {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == ErrorKind::BrokenPipe => Err(StdoutClosed.into()),
        Err(e) => Err(anyhow::Error::new(e).context("writing to stdout")),
    }
}

/// Writes `args` and a newline to stderr, dropping it if stderr is closed (what [`errln!`]
/// expands to).
pub fn stderr_line(args: fmt::Arguments<'_>) {
    let _ = writeln!(std::io::stderr().lock(), "{args}");
}

/// Prints a line on stdout like `println!`, returning `anyhow::Result<()>`: an error
/// ([`StdoutClosed`] when the reader has gone) ends the command with `?`.
macro_rules! outln {
    ($($arg:tt)*) => {
        $crate::output::stdout_line(::std::format_args!($($arg)*))
    };
}
pub(crate) use outln;

/// Prints a line on stderr like `eprintln!`, but never panics: a closed stderr drops it.
macro_rules! errln {
    ($($arg:tt)*) => {
        $crate::output::stderr_line(::std::format_args!($($arg)*))
    };
}
pub(crate) use errln;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_closed_stdout_is_found_under_context() {
        let err = anyhow::Error::new(StdoutClosed).context("printing the summary");
        assert!(is_stdout_closed(&err));
        let other = anyhow::Error::new(std::io::Error::from(ErrorKind::BrokenPipe));
        assert!(!is_stdout_closed(&other), "only stdout's own broken pipe");
    }
}
