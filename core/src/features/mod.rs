//! Fast-Hessian features: box-filter det(H) on an integral image, non-maximum suppression, grid bucketing (being written).
