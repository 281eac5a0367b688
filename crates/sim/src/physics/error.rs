//! Errors of the physics world ([`WorldError`]): a config field, an object whose hull cannot be
//! built ([`HullProblem`]) or that does not fit on the table, a non-finite pose or state, an
//! unknown handle.

use crate::physics::object::ObjectHandle;

/// Why a convex hull could not be built.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum HullProblem {
    /// The mesh has fewer than 4 vertices.
    TooFewVertices(usize),
    /// A vertex is NaN or infinite.
    NonFiniteVertex(usize),
    /// The vertices are (nearly) coplanar or collinear: the hull has no volume.
    Flat,
    /// The hull algorithm failed on these vertices.
    Failed,
}

impl std::fmt::Display for HullProblem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::TooFewVertices(n) => write!(f, "{n} vertices, at least 4 needed"),
            Self::NonFiniteVertex(i) => write!(f, "vertex {i} is not finite"),
            Self::Flat => write!(f, "the vertices are flat (no volume)"),
            Self::Failed => write!(f, "the convex-hull algorithm failed"),
        }
    }
}

/// Errors of the physics world.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WorldError {
    /// A bad [`WorldConfig`](crate::physics::config::WorldConfig) (or gripper/robot config) field.
    #[error("config: {field}: {reason}")]
    InvalidConfig {
        /// The field, e.g. `table.size_m[2]`.
        field: String,
        /// What is wrong.
        reason: String,
    },
    /// The object's convex hull cannot be built.
    #[error("object `{object}`: cannot build its convex hull: {problem}")]
    Hull {
        /// The object's name.
        object: String,
        /// Why.
        problem: HullProblem,
    },
    /// The object does not fit on the table.
    #[error(
        "object `{object}` is {extent_m} m across, larger than the table's smaller side {limit_m} m"
    )]
    ObjectTooLarge {
        /// The object's name.
        object: String,
        /// The object's largest bounding-box extent (m).
        extent_m: f32,
        /// The table's smaller horizontal side (m).
        limit_m: f32,
    },
    /// A pose with a NaN or infinite component.
    #[error("{what}: pose is not finite")]
    NonFinitePose {
        /// What the pose was for.
        what: String,
    },
    /// A handle that names no (or a removed) object.
    #[error("no object with handle {0:?}")]
    UnknownObject(ObjectHandle),
    /// A body's state became NaN or infinite during the simulation.
    #[error("object `{object}` has a non-finite pose or velocity after step {step}")]
    NonFiniteState {
        /// The object's name.
        object: String,
        /// The step count when found.
        step: u64,
    },
}
