//! The tasks a run plays: the tables it sets, packing and categories arriving over time.

pub mod arrival;
pub mod packing;
pub mod scenario;
