//! PNG/TIFF image I/O and drawing.
