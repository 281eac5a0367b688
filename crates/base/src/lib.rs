//! The plumbing every lgdm crate shares, each piece in one place: atomic files, directory locks
//! and the ownership policy of run directories ([`fs`]), seed derivation ([`seed`]), success
//! rates with Wilson intervals ([`stats`]), the progress reports long library calls give
//! their callers ([`progress`]) and the PNG charts of run directories ([`plot`]). A leaf: it
//! depends on no other lgdm crate and on nothing heavy (plotters without its default backends).
//!
//! ```
//! use lgdm_base::{fs, seed, stats::Rate};
//! let dir = tempfile::tempdir().unwrap();
//! fs::write_bytes(&dir.path().join("a.txt"), b"whole or not at all").unwrap();
//! let round_seed = seed::derive_seed(7, 0x5133_0001, 3, 0);
//! assert_ne!(round_seed, seed::derive_seed(7, 0x5133_0001, 4, 0));
//! assert_eq!(Rate::new(8, 10).describe(), "80.0 % (49.0–94.3 %, 8/10)");
//! ```

#![warn(missing_docs)]

pub mod fs;
pub mod plot;
pub mod progress;
pub mod seed;
pub mod stats;

pub use fs::{DirLock, LOCK_FILE};
pub use progress::Progress;
