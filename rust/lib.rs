//! robocal's core: kinematic calibration kernels for industrial robots.
//!
//! Pure Rust (nalgebra for small fixed-size geometry, faer for the normal equations and the
//! SVDs). `py/` is the only place that knows about Python; build with
//! `--no-default-features` to test the core without libpython.
//!
//! - [`kinematics`]: serial chains (DH, MDH, Hayati β), base and tool, forward kinematics and the
//!   parameter Jacobian of the tool frame.
//! - [`measurement`]: cable, position and pose models, batched residuals and identification
//!   Jacobians, sigma-point propagation, the closed-form cable start.
//! - [`sigma`]: Merwe scaled sigma points and the unscented transform.
//! - [`solve`]: the damped normal-equation step of LM / VSLM.
//! - [`configurations`]: which samples revisit one joint configuration (held-out splits).
//! - [`identify`]: identifiability (rank, subset, redundancy) and parameter covariance.

pub mod configurations;
pub mod error;
#[doc(hidden)]
pub mod fixtures;
pub mod identify;
pub mod kalman;
pub mod kinematics;
mod linalg;
pub mod measurement;
mod parallel;
pub mod sigma;
pub mod solve;

#[cfg(feature = "python")]
mod py;
