//! `fakeack`: exact analysis and Monte Carlo of the fake-ACK attack on ACK-based sensor power
//! schedules for remote state estimation (Li, Quevedo, Dey, Shi).
//!
//! The numerical core is plain Rust and knows nothing of Python; `bindings` (behind the `python`
//! feature) is the only module that touches PyO3.
//!
//! Notation follows the paper: `a = 1 - lam`, `tr_i = Tr h^i(P̄)`, `w_i = a^i tr_i` (the
//! *weighted* traces, which stay finite where `tr_i` alone would overflow), `tau` the holding time
//! since the last arrival and `sigma` the attacker's flag-ACK counter.

#![deny(unsafe_op_in_unsafe_fn)]
pub mod attack;
pub mod chain;
pub mod error;
pub mod general;
pub mod montecarlo;
pub mod pattern;
#[cfg(test)]
mod properties;
pub mod riccati;
pub mod rng;
pub mod schedules;
pub mod stationary;
pub mod sweep;
pub mod transient;

#[cfg(feature = "python")]
mod bindings;

pub use attack::Attack;
pub use error::{Error, Result};
