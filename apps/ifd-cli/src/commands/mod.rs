//! One module per subcommand, each a clap struct with a `run` method.

pub mod compare;
pub mod convert;
pub mod decompose;
pub mod envmap;
pub mod field;
pub mod filter;
pub mod gpu_info;
pub mod hessian;
pub mod info;
pub mod render;
pub mod shell;
pub mod sigma_map;
pub mod smooth;
pub mod sphere;
pub mod tiled;
