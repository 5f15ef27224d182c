//! The sensor's power schedules without attack, and the parameters they share: the offline
//! schedule, which ignores ACKs ([`offline`]); the ACK-based online schedule ([`online`], and its
//! exact design for parameter studies in [`exact_design`]); λ and the energy ratio
//! ([`params`]). Each cost here is one closed form, the base the attacked costs are measured
//! against.
//!
//! Every public item is also re-exported here, so `fakeack::schedule::Ratio` and the former
//! paths `fakeack::schedules::...` and `fakeack::online::...` name the same items.

pub mod exact_design;
pub mod offline;
pub mod online;
pub mod params;

pub use offline::{j_offline, offline_schedule, OfflineBlocks, MAX_PERIOD};
pub use online::{
    design_online, j_max, j_online, OnlineDesign, Walk, DESIGN_BOUNDARY_TOL, MAX_DESIGN_Z0,
};
pub use params::{apow, check_lam, one_minus_apow, Ratio};
