//! The crate's one error type. `bindings` maps each variant to a Python exception.

use std::fmt;

/// Everything that can go wrong in the numerical core.
#[derive(Debug, Clone, PartialEq)]
pub enum Error {
    /// An argument is outside its domain; `arg` names it (Python `ValueError`).
    InvalidArgument {
        /// The argument's name, as the caller spells it.
        arg: String,
        /// What is wrong with it.
        reason: String,
    },
    /// An iterative solver stopped without meeting its tolerance (Python `ValueError`).
    NotConverged {
        /// The solver.
        what: &'static str,
        /// Iterations run.
        iterations: usize,
        /// The relative residual reached.
        residual: f64,
    },
    /// A request that would need more memory than allowed; refused before allocating
    /// (Python `ValueError`).
    TooLarge {
        /// The argument that sets the size.
        arg: String,
        /// Elements the request needs.
        requested: u128,
        /// The most allowed.
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_name_the_argument() {
        let e = Error::invalid("lam", "must lie in (0, 1), got 2");
        assert_eq!(e.to_string(), "lam: must lie in (0, 1), got 2");
        let e = Error::TooLarge {
            arg: "t".into(),
            requested: 10,
            limit: 5,
        };
        assert!(
            e.to_string()
                .starts_with("t: the request needs 10 elements"),
            "{e}"
        );
        let e = Error::NotConverged {
            what: "Riccati doubling",
            iterations: 7,
            residual: 1e-3,
        };
        assert!(e.to_string().contains("after 7 iterations"), "{e}");
    }
}
