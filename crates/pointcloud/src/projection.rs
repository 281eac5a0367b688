//! Projection of clouds to 224×224 images and best-view selection.
