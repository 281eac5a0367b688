//! What the rounds ask of the robot: the tables it sets ([`scenario`]), packing by recognised
//! category ([`packing`]) and categories arriving over time ([`arrival`]). On physics, grasping
//! and recognition.

pub mod arrival;
pub mod packing;
pub mod scenario;
