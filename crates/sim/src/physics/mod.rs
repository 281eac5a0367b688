//! The physics world and the colliders of its objects.

pub mod hull;
pub mod shapes;
pub mod world;
