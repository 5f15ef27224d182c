//! Renewal forms of the attacked cost: between two fresh starts (an arrival, or the high-power
//! step after a flag-ACK reached the sensor) the detector's memory walk repeats, so each cost is a
//! ratio of sums over one cycle and never builds a chain. One file per attack family:
//! [`periodic`] (any periodic blocking mask and memory mix μ), [`independent`] (blocking each
//! flag-ACK independently, and forging), [`sweep`] (every r/t at once and the threshold β̄) and
//! [`rates`] (the flag-ACK rates all of them imply). Periodic and mask blocking under a Markov
//! channel, the channel state a phase of the renewal, is the engine's fast path `engine::markov`. The explicit chains of the `chain` module
//! are the independent check of these forms.

pub mod independent;
pub mod periodic;
pub mod rates;
pub mod sweep;
