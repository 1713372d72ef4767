//! One module per subcommand, each a clap struct with a `run` method.

pub mod brdf_filter;
pub mod compare;
pub mod convert;
pub mod decompose;
pub mod envmap;
pub mod field;
pub mod filter;
pub mod gpu_info;
pub mod hessian;
pub mod info;
pub mod mirror;
pub mod radial;
pub mod render;
pub mod smooth;
pub mod sparsity;
pub mod sphere;
pub mod tiled;
pub mod visibility;
