//! Reserved for the general exact engine: one finite automaton of channel × detector × sensor ×
//! attacker, whose stationary law and transient curves would give every cost exactly, for
//! detectors and attackers that have no renewal form ([`crate::renewal`]) and no hand-built
//! chain ([`crate::chain`]). It sits beside those routes as a further independent one.
//!
//! It holds no code yet.
