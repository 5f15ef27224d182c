//! Monte Carlo of the real protocol (work in progress).
