//! ifd facade
pub use ifd_image as image;
pub use ifd_planar as planar;
pub use ifd_smooth as smooth;
pub use ifd_sphere as sphere;
