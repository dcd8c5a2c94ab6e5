//! Tracking: robust frame-to-map pose estimation on SE(3) (being written).
