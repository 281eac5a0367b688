//! Objects, RGB-D rendering, sequential point clouds, augmentations, GOOD, MCAP datasets.
