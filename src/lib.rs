//! ifd facade
pub use ifd_image as image;
pub use ifd_planar as planar;
