//! Run-time CPU capabilities, as tokens. Code compiled for an instruction-set extension
//! (`#[target_feature]`) is undefined behaviour on a CPU without it, so the kernels built for one
//! are reached only through a token that proves the CPU has it.

use std::fmt;

/// Proof that the CPU running this process supports AVX2. The only way to get one is
/// [`Avx2::detect`], which asks the CPU; the AVX2 kernels must be given one.
#[derive(Clone, Copy, PartialEq, Eq)]
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
pub(super) struct Avx2 {
    /// Private, so that no code outside this module can make a token.
    _private: (),
}

impl Avx2 {
    /// `Some` iff the CPU supports AVX2 (never on other architectures than x86-64).
    pub(super) fn detect() -> Option<Self> {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            return Some(Avx2 { _private: () });
        }
        None
    }
}

impl fmt::Debug for Avx2 {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("Avx2")
    }
}
