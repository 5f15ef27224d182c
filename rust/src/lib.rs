//! `fakeack`: exact analysis and Monte Carlo of the fake-acknowledgment attack on ACK-based
//! sensor power schedules for remote state estimation, after Y. Li, D. E. Quevedo, S. Dey and
//! L. Shi, *Fake-Acknowledgment Attack on ACK-based Sensor Power Schedule for Remote State
//! Estimation*, in the corrected model (the README's "Model notes" list each correction).
//!
//! A smart sensor runs a Kalman filter and sends its estimate over a lossy link, at high power
//! (always arrives) or low power (arrives with probability λ) under an energy budget. The remote
//! side's event detector turns runs of losses into flag-ACKs that ask for high power (the online
//! schedule); an attacker who blocks a fraction β of them degrades the estimate, and past a
//! threshold β̄ the sensor does better ignoring ACKs (the offline schedule).
//!
//! # Where to start
//! [`LinearSystem`] holds a system and its steady-state covariance P̄, and has a method for every
//! quantity: [`j_offline`](LinearSystem::j_offline), [`j_online`](LinearSystem::j_online),
//! [`j_max`](LinearSystem::j_max), [`j_attack`](LinearSystem::j_attack) under any [`Attack`],
//! [`j_attack_limit`](LinearSystem::j_attack_limit), [`beta_sweep`](LinearSystem::beta_sweep),
//! [`beta_bar`](LinearSystem::beta_bar) (both thresholds),
//! [`choose_schedule`](LinearSystem::choose_schedule) (the sensor's decision),
//! [`worst_mask`](LinearSystem::worst_mask),
//! [`expected_trace_curve`](LinearSystem::expected_trace_curve) (exact finite-horizon curves) and
//! [`simulate`](LinearSystem::simulate) (Monte Carlo of the protocol). The online schedule's
//! parameters are an [`OnlineDesign`], from [`design_online`] or given; the budget is a
//! [`Ratio`]; [`flag_rates`] gives the flag-ACK rates.
//!
//! ```
//! use fakeack::{design_online, Attack, LinearSystem, Ratio};
//!
//! let system = LinearSystem::scalar(1.2, 0.7, 0.8, 0.8)?; // the paper's example
//! let (lam, ratio) = (0.5, Ratio::new(1, 7)?);
//! let design = design_online(lam, ratio)?; // z0 = 2, mu = 1
//! let j_off = system.j_offline(lam, ratio)?;
//! let j_att = system.j_attack(lam, design, &Attack::periodic(1, 5)?)?;
//! let bar = system.beta_bar(lam, ratio, design, 60)?;
//! assert!(j_att < j_off && 0.32 < bar.limit && bar.limit < 0.33);
//! # Ok::<(), fakeack::Error>(())
//! ```
//!
//! `examples/paper.rs` (`cargo run --release --example paper`) prints every number of the
//! paper's example.
//!
//! # Layout
//! The modules follow the independent routes the crate computes each cost by, so that one route
//! can check another:
//! * [`system`]: the model and its closed forms (P̄ by [`riccati`], [`stein`], [`spectral`]);
//! * [`schedule`]: the schedules without attack (offline, online) and the parameters they share;
//! * [`chain`]: explicit chains (the paper's attack chain, the general chain, their stationary
//!   solvers and exact transient curves);
//! * [`renewal`]: renewal forms of the attacked cost (periodic masks, independent blocking, the
//!   β sweep, flag-ACK rates);
//! * [`montecarlo`]: simulation of the real protocol and of the closed-loop game, with its own
//!   random number generator ([`rng`]);
//! * [`grid`]: parameter studies over many cells; [`analysis`]: the methods of [`LinearSystem`]
//!   that tie the routes together; [`attack`] and [`error`]: what all of them share;
//! * [`engine`]: the general exact engine, one automaton of channel × detector × sensor ×
//!   attacker for any Markov channel, schedule and finite attacker ([`Scenario`]).
//!
//! The paths of the former flat layout (`fakeack::riccati`, `fakeack::pattern`,
//! `fakeack::online`, ...) are re-exported here and still resolve.
//!
//! # Notation
//! Following the paper: `a = 1 - lam`, `tr_i = Tr h^i(P̄)`, `w_i = a^i tr_i` (the *weighted*
//! traces, which stay finite where `tr_i` alone would overflow), `tau` the holding time since the
//! last arrival and `sigma` the attacker's flag-ACK counter.
//!
//! The numerical core is plain Rust; the `python` feature adds the PyO3 bindings of the Python
//! package `fakeack` (a private module that only converts types).

#![warn(missing_docs)]
#![deny(unsafe_op_in_unsafe_fn)]

pub mod analysis;
pub mod attack;
pub mod chain;
pub mod engine;
pub mod error;
pub mod grid;
pub mod montecarlo;
#[cfg(test)]
mod properties;
pub mod renewal;
pub mod schedule;
pub mod system;

#[cfg(feature = "python")]
mod bindings;

pub use analysis::{flag_rates, BetaBar, Decision, FlagRates, MaskSearch, Schedule};
pub use attack::Attack;
pub use engine::{Attacker, AttackerAutomaton, Channel, Engine, Move, PowerSchedule, Scenario};
pub use error::{Error, Result};
pub use montecarlo::{McConfig, McResult, McSchedule, Mode, Protocol};
pub use renewal::sweep::Sweep;
pub use schedule::{design_online, OnlineDesign, Ratio};
pub use system::LinearSystem;

// The former top-level modules, now files of the groups above: their old paths still resolve.
pub use chain::{general, stationary, transient};
pub use montecarlo::rng;
pub use renewal::{independent as random, periodic as pattern, sweep};
pub use schedule as online;
pub use schedule as schedules;
pub use schedule::exact_design;
pub use system::{riccati, spectral, stein};
