//! Recognition in the loop and the model a run starts from.

pub mod model;
pub mod recognize;
