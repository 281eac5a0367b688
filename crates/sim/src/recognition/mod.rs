//! Recognition in the loop and the model a run starts from.

pub mod config;
pub mod encoder;
pub mod error;
pub mod labels;
pub mod model;
pub mod recognizer;
pub mod views;
