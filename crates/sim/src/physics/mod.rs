//! The physics world: rapier3d with the reference table, baskets and floor ([`world`]), its
//! constants ([`config`]) and errors ([`error`]), the dynamic objects' handles and drawings
//! ([`object`]), where they are dropped ([`drop_region`]), their colliders ([`shapes`] on
//! [`hull`]) and what an object's geometry says about grasping it ([`measure`]). Uses nothing
//! else of the crate.

pub mod config;
pub mod drop_region;
pub mod error;
pub mod hull;
pub mod measure;
pub mod object;
pub(crate) mod rapier;
pub mod shapes;
pub mod world;
