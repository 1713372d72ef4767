//! One module per subcommand, each a clap struct with a `run` method.

pub mod compare;
pub mod decompose;
pub mod field;
pub mod filter;
