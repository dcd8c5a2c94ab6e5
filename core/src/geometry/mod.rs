//! Geometry: SE(3), the pinhole camera, alignment. (Being written.)
