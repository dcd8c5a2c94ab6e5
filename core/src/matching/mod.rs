//! Region matching: ROI templates tried under a bank of affine transforms, sub-pixel refinement (being written).
