//! Images: borrowed views with stride, 2x downsampling, and the image variation of the paper's
//! Eq. 3 (`v_m`, `W(I)`).

mod view;

pub use view::{DepthView, GrayView, GrayViewMut, ImageError, ImageView, ImageViewMut};
