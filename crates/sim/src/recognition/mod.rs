//! Recognition in the loop: the robot's views of an object ([`views`]) through a view encoder
//! ([`encoder`]) into the dual memory's first guess, the teacher's lessons and replay
//! ([`recognizer`]); the names of its ids ([`labels`]), its constants ([`config`]) and errors
//! ([`error`]); the model a pick-and-place run starts from and leaves ([`model`]). On physics
//! and perception.

pub mod config;
pub mod encoder;
pub mod error;
pub mod labels;
pub mod model;
pub mod recognizer;
pub mod views;
