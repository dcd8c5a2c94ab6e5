//! Images: borrowed views with stride, 2x downsampling, and the image variation of the paper's
//! Eq. 3 (`v_m`, `W(I)`).
//!
//! - [`ImageView`] / [`ImageViewMut`] and their gray and depth aliases: the caller owns the pixels.
//! - [`downsample_gray_2x`] (rounded 2x2 mean) and [`downsample_depth_2x`] (a real sample per
//!   block, never an average across an object edge): one pyramid level, VGA to QVGA; and their
//!   streaming forms [`downsample_gray_row_pair`] / [`downsample_depth_row_pair`], which halve a
//!   sensor frame two rows at a time while it arrives.
//! - [`variation`], [`variation_map`] and [`total_variation`]: `v_m` and `W(I)` of Eq. 3.

mod downsample;
mod variation;
mod view;

pub use downsample::{
    downsample_depth_2x, downsample_depth_row_pair, downsample_gray_2x, downsample_gray_row_pair,
};
pub use variation::{total_variation, variation, variation_map};
pub use view::{
    DepthView, GrayView, GrayViewMut, ImageError, ImageView, ImageViewMut, MAX_DEPTH_LEVEL,
};
