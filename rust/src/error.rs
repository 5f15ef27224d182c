//! The crate's one error type. `bindings` maps each variant to a Python exception.

use std::fmt;

/// Everything that can go wrong in the numerical core.
#[derive(Debug, Clone, PartialEq)]
pub enum Error {
    /// An argument is outside its domain; `arg` names it (Python `ValueError`).
    InvalidArgument { arg: String, reason: String },
    /// An iterative solver stopped without meeting its tolerance (Python `ValueError`).
    NotConverged {
        what: &'static str,
        iterations: usize,
        residual: f64,
    },
    /// A request that would need more memory than allowed; refused before allocating
    /// (Python `ValueError`).
    TooLarge {
        arg: String,
        requested: u128,
        limit: u128,
    },
    /// The caller asked the computation to stop (Python `KeyboardInterrupt`).
    Interrupted,
}

/// `Result` with the crate's error.
pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    /// Shorthand for [`Error::InvalidArgument`].
    pub fn invalid(arg: impl Into<String>, reason: impl Into<String>) -> Self {
        Error::InvalidArgument {
            arg: arg.into(),
            reason: reason.into(),
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::InvalidArgument { arg, reason } => write!(f, "{arg}: {reason}"),
            Error::NotConverged {
                what,
                iterations,
                residual,
            } => write!(
                f,
                "{what} did not converge after {iterations} iterations (relative residual {residual:.3e})"
            ),
            Error::TooLarge {
                arg,
                requested,
                limit,
            } => write!(
                f,
                "{arg}: the request needs {requested} elements, more than the limit of {limit}; refused before allocating"
            ),
            Error::Interrupted => write!(f, "interrupted"),
        }
    }
}

impl std::error::Error for Error {}

/// Checks `0 < lam < 1` (the low-power arrival probability λ).
pub fn check_lam(lam: f64) -> Result<()> {
    if lam.is_finite() && lam > 0.0 && lam < 1.0 {
        Ok(())
    } else {
        Err(Error::invalid(
            "lam",
            format!("must lie in (0, 1), got {lam}"),
        ))
    }
}

/// Checks `0 <= mu <= 1`.
pub fn check_mu(mu: f64) -> Result<()> {
    if mu.is_finite() && (0.0..=1.0).contains(&mu) {
        Ok(())
    } else {
        Err(Error::invalid(
            "mu",
            format!("must lie in [0, 1], got {mu}"),
        ))
    }
}

/// Checks `z0 >= 1` and `0 <= r < t`.
pub fn check_attack(z0: u64, r: u64, t: u64) -> Result<()> {
    if z0 < 1 {
        return Err(Error::invalid(
            "z0",
            format!("must be at least 1, got {z0}"),
        ));
    }
    if t < 1 {
        return Err(Error::invalid("t", format!("must be at least 1, got {t}")));
    }
    if r >= t {
        return Err(Error::invalid(
            "r",
            format!("must be smaller than t = {t}, got r = {r}"),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_name_the_argument() {
        let e = check_lam(1.5).unwrap_err();
        assert!(e.to_string().starts_with("lam:"), "{e}");
        let e = check_attack(2, 3, 3).unwrap_err();
        assert!(e.to_string().starts_with("r:"), "{e}");
        let e = check_attack(0, 0, 3).unwrap_err();
        assert!(e.to_string().starts_with("z0:"), "{e}");
        assert!(check_mu(f64::NAN).is_err());
    }
}
