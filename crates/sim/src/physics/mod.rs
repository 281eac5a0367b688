//! The physics world and the colliders of its objects.

pub mod config;
pub mod drop;
pub mod error;
pub mod hull;
pub mod measure;
pub mod object;
pub(crate) mod rapier;
pub mod shapes;
pub mod world;
