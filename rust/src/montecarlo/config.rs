//! The public description of an experiment ([`McConfig`]) and of its outcome ([`McResult`]).

use crate::attack::Attack;

/// The sensor's power schedule.
#[derive(Debug, Clone, PartialEq)]
pub enum McSchedule {
    /// A fixed pattern repeated periodically (the offline schedule).
    Offline {
        /// The power at each step of a period: 1 = high power Δ, 0 = low power δ; `pattern[0]`
        /// must be 1 (the sensor uses Δ at k = 1).
        pattern: Vec<u8>,
    },
    /// The ACK-based online schedule: z0-bit memory with probability `mu`, else z0+1 bits.
    Online {
        /// The short memory length, >= 1: a flag-ACK after z0 zero ACKs in a row.
        z0: u64,
        /// The probability μ of using the z0-bit memory at a step, in [0, 1] (Model note 2).
        mu: f64,
    },
}

/// What each run tracks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// τ_k only; accumulates Tr P_k = `tr[τ_k]` = Tr h^τ_k(P̄).
    Covariance,
    /// The estimation errors themselves, with real Gaussian noise. The sensor's steady-state
    /// Kalman filter (gain K = P⁻C'(CP⁻C'+R)^{-1}, P⁻ = AP̄A'+Q) has error
    /// e^s_k = (I-KC)(A e^s_{k-1} + w_{k-1}) - K v_k, started stationary e^s_0 ~ N(0, P̄); the
    /// remote error is e_k = e^s_k on arrival, else A e_{k-1} + w_{k-1} (the same w draw).
    /// Accumulates ||e_k||², whose mean is `Tr E[P_k]`.
    ///
    /// Simulating the errors rather than the state x_k keeps an unstable A from overflowing: x_k
    /// grows like ρ(A)^k over the whole horizon (1.2^k overflows f64 after ~3900 steps), while
    /// e_k only grows during a run of losses and restarts from e^s_k at every arrival. An error
    /// that does overflow (an astronomically long loss run) is reported as +inf, never NaN.
    State,
}

/// How the flag-ACK travels from the detector to the sensor.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Protocol {
    /// One bit every step (1 = flag); the attacker flips 1-bits to 0 (integrity attack).
    A,
    /// A flag packet only when a flag is due; the attacker drops it (DoS).
    B,
}

/// A two-state Markov (Gilbert-Elliott) channel on which a high-power packet always arrives:
/// state 0 (good) and state 1 (bad). Given the state c_k, the packet of step k arrives
/// independently of everything else (always at high power, with probability `low[c_k]` at low
/// power); c_1 has the stationary law (P(c_1 = 0) = q / (p + q)); after each step the channel
/// moves by P = [[1 - p, p], [q, 1 - q]].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TwoStateChannel {
    /// P(c_{k+1} = 1 | c_k = 0), in [0, 1].
    pub p: f64,
    /// P(c_{k+1} = 0 | c_k = 1), in [0, 1]; p + q > 0 (one closed class).
    pub q: f64,
    /// Low-power arrival probability in state 0 and in state 1, each in [0, 1].
    pub low: [f64; 2],
}

/// One Monte Carlo experiment.
#[derive(Debug, Clone, PartialEq)]
pub struct McConfig {
    /// Low-power arrival probability λ of the paper's i.i.d. channel, in (0, 1); not read when
    /// [`McConfig::channel`] is given.
    pub lam: f64,
    /// A two-state Markov channel instead of the i.i.d. one (`None`: the paper's channel of
    /// `lam`). Covariance mode only, and only on the bit-sliced kernel: a plan outside its
    /// limits is refused (see [`simulate_if_supported`](super::simulate_if_supported)).
    pub channel: Option<TwoStateChannel>,
    /// The sensor's power schedule.
    pub schedule: McSchedule,
    /// The attack on the flag-ACKs (online schedule only): [`Attack::Periodic`] blocks the first
    /// r of every t, [`Attack::Mask`] any periodic mask over the attacker's flag counter (a mask
    /// of all ones blocks every flag, and the runs estimate J_max), [`Attack::Random`] blocks
    /// each flag independently with probability β, and [`Attack::Injection`] forges a flag-ACK
    /// with probability γ on every step without a genuine one (beside any of the blocking
    /// attacks on the genuine flags). `None`: no attacker.
    pub attack: Option<Attack>,
    /// Covariance (τ only) or state (Gaussian errors) fidelity.
    pub mode: Mode,
    /// How the flag-ACK travels (A and B give identical results for the same seed).
    pub protocol: Protocol,
    /// Steps per run, 1..=[`MAX_HORIZON`](super::MAX_HORIZON).
    pub horizon: usize,
    /// Number of independent runs, >= 1.
    pub runs: u64,
    /// The results depend on this seed only (not on threads or CPU features).
    pub seed: u64,
    /// Record each run's number of delivered flag-ACKs in [`McResult::delivered_per_run`]
    /// (8 bytes per run, at most 2^28 runs). `false`: nothing extra is kept.
    pub record_runs: bool,
}

/// Averages over the runs.
#[derive(Debug, Clone, PartialEq)]
pub struct McResult {
    /// Length `horizon`: average over runs of Tr P_k (covariance) or ||e_k||² (state), k = 1..
    pub mean_trace: Vec<f64>,
    /// J_k = (1/k) Σ_{i<=k} `mean_trace[i]` (a compensated running sum).
    pub j_k: Vec<f64>,
    /// `j_k[horizon-1]`, the mean over runs of each run's time average.
    pub j: f64,
    /// Standard error of `j`: sample standard deviation of the per-run time averages over
    /// sqrt(runs). `+inf` with a single run (no spread can be estimated) or when some run's
    /// average is infinite; never NaN.
    pub stderr: f64,
    /// Fraction of steps at high power Δ: the initial step and every step after a flag-ACK
    /// reached the sensor, genuine or forged.
    pub high_power_rate: f64,
    /// Flag-ACKs sent by the detector, per step (genuine ones only).
    pub flags_sent: f64,
    /// Genuine flag-ACKs blocked (protocol B) or flipped to 0 (protocol A) by the attacker, per
    /// step.
    pub flags_blocked: f64,
    /// Flag-ACKs forged by the attacker ([`Attack::Injection`]), per step: flag packets it sent
    /// (protocol B) or 0-bits it flipped to 1 (protocol A) on steps without a genuine flag. The
    /// sensor cannot tell them from genuine ones, so the flag-ACKs reaching it per step are
    /// `flags_sent - flags_blocked + flags_forged`.
    pub flags_forged: f64,
    /// Number of runs.
    pub runs: u64,
    /// Steps per run (= horizon).
    pub steps: u64,
    /// Only with [`McConfig::record_runs`] (else empty, never allocated): entry i is the number
    /// of flag-ACKs delivered to the sensor during run i over steps 1..=horizon: those sent by
    /// the detector and neither blocked (protocol B) nor flipped (protocol A), plus those the
    /// attacker forged (the sensor cannot tell them apart); a flag delivered at the last step
    /// counts, and the initial high-power step at k = 1 is not a flag. Runs are
    /// in run order: run i is position i % [`BLOCK_RUNS`](super::BLOCK_RUNS) of block i / [`BLOCK_RUNS`](super::BLOCK_RUNS), so the
    /// entries depend on the seed only (not on threads or kernels), and a run's entry does not
    /// depend on how many runs follow it. All zeros for an offline schedule (no flags). Its mean
    /// over runs, divided by the horizon, is `flags_sent - flags_blocked + flags_forged`.
    ///
    /// Memory: the one output that grows with `runs`, 8 bytes per run (2 GiB at the limit of
    /// 2^28 runs; more is refused with [`Error::TooLarge`](crate::Error::TooLarge)).
    pub delivered_per_run: Vec<u64>,
}
