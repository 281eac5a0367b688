//! Errors of recognition ([`RecognitionError`]): a config field, a model of another feature
//! dimension than the encoder's, the encoder, the dual memory, rendering a view, the world.

use lgdm_gdm::GdmError;

use crate::perception::camera::CameraError;
use crate::physics::error::WorldError;

use crate::recognition::encoder::EncoderError;

/// Errors of recognition.
#[derive(Debug, thiserror::Error)]
pub enum RecognitionError {
    /// A bad [`RecognitionConfig`](crate::recognition::config::RecognitionConfig) field.
    #[error("recognition config: {field}: {reason}")]
    InvalidConfig {
        /// The field.
        field: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// The model does not take the encoder's features.
    #[error(
        "the model expects {model}-d features but the {name} encoder gives {encoder}-d: was it \
         trained with another encoder?"
    )]
    Dimension {
        /// The model's input dimension.
        model: usize,
        /// The encoder's name.
        name: String,
        /// The encoder's dimension.
        encoder: usize,
    },
    /// The encoder failed on the views.
    #[error("the {name} encoder failed")]
    Encoder {
        /// The encoder's name.
        name: String,
        /// What went wrong.
        source: EncoderError,
    },
    /// The dual memory failed.
    #[error("dual memory: {0}")]
    Model(#[from] GdmError),
    /// Rendering a view failed.
    #[error(transparent)]
    Camera(#[from] CameraError),
    /// A world query failed.
    #[error(transparent)]
    World(#[from] WorldError),
}
