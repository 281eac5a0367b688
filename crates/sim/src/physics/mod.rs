//! The physics world and the colliders of its objects.

pub mod hull;
pub mod measure;
pub mod shapes;
pub mod world;
