//! How accurately a decomposition is applied, and the stack that applies it
//! accurately enough: the evaluation plan.
//!
//! The plan ([`EvalPlan`], `plan.rs`) weighs each candidate stack's expected
//! error on white noise (`white_noise.rs`) against its cost (`cost.rs`); the
//! error of one read (`read_error.rs`) gives its bound, and the kernel's norm
//! (`norm.rs`) normalises both. Several decompositions read from one stack
//! share one plan (`shared.rs`).

mod cost;
mod norm;
mod plan;
mod read_error;
mod shared;
mod white_noise;

pub use plan::{EvalPlan, PlanOptions};
pub use read_error::{level_blend_error, lookup_error, nearest_level_error};
