//! The general exact engine: one finite automaton E of channel × detector × sensor × attacker,
//! whose stationary law and coupled Stein equations give every cost exactly, for channels with
//! memory, any schedule and attackers that have no renewal form ([`crate::renewal`]) and no
//! hand-built chain ([`crate::chain`]). It shares no formula with those routes, so it is a
//! further independent check of them.
//!
//! # The model
//! A state e_k holds everything but the holding time τ_k after step k: the channel state, the
//! detector's zero count, the sensor's next power (or its offline phase) and the attacker's
//! state ([`product`]). Each step moves e by K = K0 + K1, split by whether the packet arrives
//! (K1: τ -> 0) or not (K0: τ -> τ + 1). With π_E the stationary law of K, ν = π_E K1 and
//! w = (I - K0)^-1 1, the law of (τ, e) is ν K0^τ and
//!
//! Z_e = b_e + Σ_f K0[e, f] A Z_f A',  b_e = P̄ + (w_e - 1) Q,  J = Tr Σ_e ν_e Z_e.
//!
//! J is finite iff ρ(K0) ρ(A)² < 1, decided by an M-matrix test (the solution of
//! (I - ρ(A)² K0) x = 1 exists and is positive), never by eigenvalue iteration.
//!
//! # The solvers
//! Sparse LU (faer, COLAMD ordering, one symbolic analysis reused for every shift of I - s K0;
//! dense LU below [`linsolve::DENSE_MAX`] states). A scalar system is one solve. A vector system
//! is brought to complex Schur form A = U T U* and Z̃_e = U* Z_e U is solved entry by entry, in
//! an order where every other term is known: entry (i, j) is one sparse solve with
//! I - t_ii conj(t_jj) K0, n(n+1)/2 of them by Hermitian symmetry. The Schur form is unitary, so
//! this is accurate for non-normal and defective A (a Jordan block), where an eigendecomposition
//! is not.
//!
//! # The parts
//! [`Channel`] (Markov, validated), [`PowerSchedule`] (online design or offline pattern),
//! [`AttackerAutomaton`] (every built-in [`Attack`], injection with a minimum gap, mimicry, or
//! given by hand), [`Engine`] (the explored product and its solves, independent of the system;
//! or an automaton given as K0 and K1, [`Engine::from_automaton`]) and [`Scenario`] (a system
//! with an engine).

pub mod attacker;
pub mod channel;
mod given;
mod graph;
pub mod linsolve;
pub mod markov;
pub mod product;
mod solve;
#[cfg(test)]
mod tests;

use std::sync::OnceLock;

pub use attacker::{AttackerAutomaton, Move};
pub use channel::Channel;
pub use given::{Triplets, ROW_SUM_TOL};
pub use product::{Explored, Origin, PowerSchedule, Product, SparseRows, StateParts};

use crate::attack::Attack;
use crate::chain::transient::MAX_WORK;
use crate::error::{Error, Result};
use crate::renewal::rates::FlagRates;
use crate::schedule::{offline_schedule, OnlineDesign, Ratio};
use crate::system::LinearSystem;
use solve::{Stationary, Stop};
use std::sync::atomic::AtomicBool;

/// Default limit on the product's states.
pub const DEFAULT_MAX_STATES: usize = 10_000_000;

/// The attacker of a scenario.
#[derive(Debug, Clone, PartialEq)]
pub enum Attacker {
    /// No attack: every genuine flag-ACK is delivered, none forged.
    None,
    /// A built-in attack; `min_gap` restricts flag injection (1: no restriction).
    Attack {
        /// The attack.
        attack: Attack,
        /// Forge at step k only if k - k_last >= min_gap (injection only; 1 otherwise).
        min_gap: u64,
    },
    /// The mimicry attacker running a virtual attack-free system of its own.
    Mimicry {
        /// The virtual channel.
        channel: Channel,
        /// The virtual detector's design.
        design: OnlineDesign,
    },
    /// An automaton given by hand.
    Automaton(AttackerAutomaton),
}

impl Attacker {
    /// A built-in attack with no minimum gap.
    pub fn attack(attack: Attack) -> Self {
        Attacker::Attack { attack, min_gap: 1 }
    }

    /// The argument an error about this attacker names.
    fn arg(&self) -> &'static str {
        match self {
            Attacker::None => "channel",
            Attacker::Attack { .. } => "attack",
            Attacker::Mimicry { .. } => "mimicry",
            Attacker::Automaton(_) => "automaton",
        }
    }

    /// An upper bound on the compiled automaton's states, known before compiling it.
    pub(crate) fn size_bound(&self) -> u128 {
        fn of(a: &Attack) -> u128 {
            match a {
                Attack::Periodic { t, .. } => u128::from(*t),
                Attack::Mask(m) => m.len() as u128,
                Attack::Random { .. } => 1,
                Attack::Injection { block, .. } => block.as_deref().map_or(1, of),
            }
        }
        match self {
            Attacker::None => 1,
            Attacker::Attack { attack, min_gap } => match attack {
                Attack::Injection { .. } => of(attack) * u128::from((*min_gap).max(1)),
                _ => of(attack),
            },
            Attacker::Mimicry { channel, design } => {
                channel.n_states() as u128 * (u128::from(design.z0) + 1) * 2 + 1
            }
            Attacker::Automaton(a) => a.n_states() as u128,
        }
    }

    fn compile(&self) -> Result<AttackerAutomaton> {
        match self {
            Attacker::None => Ok(AttackerAutomaton::none()),
            Attacker::Attack { attack, min_gap } => {
                AttackerAutomaton::from_attack(attack, *min_gap)
            }
            Attacker::Mimicry { channel, design } => AttackerAutomaton::mimicry(channel, *design),
            Attacker::Automaton(a) => Ok(a.clone()),
        }
    }
}

impl PowerSchedule {
    /// The paper's optimal offline pattern for the energy budget `ratio` (Model note 1).
    pub fn offline_ratio(ratio: Ratio) -> Result<Self> {
        Ok(PowerSchedule::Offline(
            offline_schedule(ratio)?
                .into_iter()
                .map(|g| g == 1)
                .collect(),
        ))
    }
}

/// The automaton in exchange form: a label per state, K0 and K1 as COO (rows, cols, vals).
#[derive(Debug, Clone, PartialEq)]
pub struct AutomatonExport {
    /// One readable label per state.
    pub labels: Vec<String>,
    /// K0 (lost packet) as (rows, cols, vals).
    pub k0: (Vec<i64>, Vec<i64>, Vec<f64>),
    /// K1 (arrived packet) as (rows, cols, vals).
    pub k1: (Vec<i64>, Vec<i64>, Vec<f64>),
}

/// The explored product automaton and its system-independent solves (cached on first use).
pub struct Engine {
    product: Product,
    arg: &'static str,
    stationary: OnceLock<Result<Stationary>>,
    rho_k0: OnceLock<Result<f64>>,
}

impl std::fmt::Debug for Engine {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Engine")
            .field("n_states", &self.product.n())
            .finish_non_exhaustive()
    }
}

impl Engine {
    /// Builds the product of `channel`, `schedule` and `attacker` over the states reachable from
    /// the paper's initial condition (high power at k = 1, memory all ones, the attacker at its
    /// start, c_1 stationary; an offline pattern's first symbol is step 1). Refused before
    /// allocating past `max_states` states; an offline schedule takes no attacker. Refused too,
    /// naming the channel or the attacker, when from some state no packet ever arrives again
    /// (ρ(K0) = 1).
    pub fn new(
        channel: &Channel,
        schedule: &PowerSchedule,
        attacker: &Attacker,
        max_states: usize,
    ) -> Result<Self> {
        if matches!(schedule, PowerSchedule::Offline(_)) && *attacker != Attacker::None {
            return Err(Error::invalid(
                attacker.arg(),
                "an offline schedule ignores ACKs, so an attack has no effect",
            ));
        }
        let na = attacker.size_bound();
        if na > max_states as u128 {
            return Err(Error::TooLarge {
                arg: attacker.arg().into(),
                requested: na,
                limit: max_states as u128,
            });
        }
        let automaton = attacker.compile()?;
        let product = product::explore(channel, schedule, &automaton, max_states)?;
        graph::check_arrivals(&product, attacker.arg())?;
        Ok(Engine {
            product,
            arg: attacker.arg(),
            stationary: OnceLock::new(),
            rho_k0: OnceLock::new(),
        })
    }

    fn stationary(&self) -> Result<&Stationary> {
        self.stationary
            .get_or_init(|| Stationary::new(&self.product, self.arg))
            .as_ref()
            .map_err(Clone::clone)
    }

    /// The product automaton.
    pub fn product(&self) -> &Product {
        &self.product
    }

    /// Number of automaton states.
    pub fn n_states(&self) -> usize {
        self.product.n()
    }

    /// Checks that a packet arrives again from every state (ρ(K0) < 1) and solves the stationary
    /// law; returns ||π K - π||_1.
    pub fn stationary_residual(&self) -> Result<f64> {
        Ok(self.stationary()?.residual)
    }

    /// The stationary law π_E of K.
    pub fn stationary_law(&self) -> Result<&[f64]> {
        Ok(&self.stationary()?.pi)
    }

    /// The long-run cost J = lim E Tr P_k; +inf when ρ(K0) ρ(A)² >= 1, never NaN.
    pub fn cost(&self, system: &LinearSystem) -> Result<f64> {
        self.cost_cancellable(system, None)
    }

    /// [`Engine::cost`], stopping with [`Error::Interrupted`] between solves once `cancel` is set.
    pub fn cost_cancellable(
        &self,
        system: &LinearSystem,
        cancel: Option<&AtomicBool>,
    ) -> Result<f64> {
        solve::cost(self.stationary()?, &self.product.k0, system, Stop(cancel))
    }

    /// ρ(K0), to ~1e-13 relative (0 when the holding time is bounded).
    pub fn rho_k0(&self) -> Result<f64> {
        self.rho_k0_cancellable(None)
    }

    /// [`Engine::rho_k0`], stopping between M-matrix tests once `cancel` is set (an interrupted
    /// bisection is not cached).
    pub fn rho_k0_cancellable(&self, cancel: Option<&AtomicBool>) -> Result<f64> {
        if let Some(r) = self.rho_k0.get() {
            return r.clone();
        }
        let st = self.stationary()?;
        let r = st.rho_k0(&self.product.k0, Stop(cancel));
        if r != Err(Error::Interrupted) {
            let _ = self.rho_k0.set(r.clone());
        }
        r
    }

    /// The stability index ρ(K0) ρ(A)²: J is finite iff it is below 1.
    pub fn stability_index(&self, system: &LinearSystem) -> Result<f64> {
        self.stability_index_cancellable(system, None)
    }

    /// [`Engine::stability_index`] with a cancellation flag.
    pub fn stability_index_cancellable(
        &self,
        system: &LinearSystem,
        cancel: Option<&AtomicBool>,
    ) -> Result<f64> {
        let r = system.spectral_radius();
        Ok(self.rho_k0_cancellable(cancel)? * r * r)
    }

    /// Long-run fraction of steps at high power; an error for an automaton given as K0 and K1
    /// ([`Engine::from_automaton`]), which carries no power information.
    pub fn high_power_rate(&self) -> Result<f64> {
        let explored = self.product.explored()?;
        let st = self.stationary()?;
        Ok(st
            .pi
            .iter()
            .zip(&explored.high_next)
            .filter(|(_, &h)| h)
            .map(|(p, _)| p)
            .sum())
    }

    /// Long-run flag-ACKs per step: sent by the detector, delivered to the sensor, forged; an
    /// error for an automaton given as K0 and K1, which carries no flag-ACK information.
    pub fn flag_rates(&self) -> Result<FlagRates> {
        let explored = self.product.explored()?;
        let pi = &self.stationary()?.pi;
        let dot = |v: &[f64]| pi.iter().zip(v).map(|(a, b)| a * b).sum::<f64>();
        Ok(FlagRates {
            sent: dot(&explored.sent),
            delivered: dot(&explored.delivered),
            forged: dot(&explored.forged),
        })
    }

    /// The stationary law of the holding time: P(τ = 0..n-1) and, last, P(τ >= n) = ν K0^n w.
    pub fn holding_time_law(&self, n: usize) -> Result<Vec<f64>> {
        let st = self.stationary()?;
        let k0 = &self.product.k0;
        check_work(n, k0.data.len() + self.n_states(), "n")?;
        let mut v = st.nu.clone();
        let mut next = vec![0.0; v.len()];
        let mut out = Vec::with_capacity(n + 1);
        for _ in 0..n {
            out.push(v.iter().sum());
            k0.left_mul(&v, &mut next);
            std::mem::swap(&mut v, &mut next);
        }
        out.push(v.iter().zip(&st.w).map(|(a, b)| a * b).sum());
        Ok(out)
    }

    /// Exact E Tr P_k and J_k (the mean of the first k) for k = 1..=horizon from the paper's
    /// initial condition. The law of (τ, e) is carried as S_k(e) = Σ_τ P(τ_k = τ, e_k = e)
    /// h^τ(P̄) with S_{k+1}(f) = (L_k K1)(f) P̄ + Σ_e K0[e, f] (A S_k(e) A' + L_k(e) Q), L_k the
    /// law of e_k: exact, with no cap on τ, and finite wherever the true value is (a weight and
    /// a trace are never formed apart). Values past the double range are +inf.
    pub fn cost_curve(
        &self,
        system: &LinearSystem,
        horizon: usize,
    ) -> Result<(Vec<f64>, Vec<f64>)> {
        self.cost_curve_cancellable(system, horizon, None)
    }

    /// [`Engine::cost_curve`], stopping between steps once `cancel` is set.
    pub fn cost_curve_cancellable(
        &self,
        system: &LinearSystem,
        horizon: usize,
        cancel: Option<&AtomicBool>,
    ) -> Result<(Vec<f64>, Vec<f64>)> {
        let stop = Stop(cancel);
        if horizon == 0 {
            return Err(Error::invalid("horizon", "must be at least 1"));
        }
        let p = &self.product;
        let (n, nx) = (p.n(), system.n());
        let nn = nx * nx;
        check_work(
            horizon,
            p.k0.data.len() * nn + p.k1.data.len() + n * nn * nx,
            "horizon",
        )?;
        let a = system.a();
        let (pbar, q) = (system.pbar(), system.q());
        let mut law = p.init.clone();
        let mut s = vec![0.0; n * nn];
        for e in 0..n {
            for (x, &pv) in s[e * nn..(e + 1) * nn].iter_mut().zip(pbar.as_slice()) {
                *x = law[e] * pv;
            }
        }
        let mut next_law = vec![0.0; n];
        let mut arrive = vec![0.0; n];
        let mut next_s = vec![0.0; n * nn];
        let mut m = vec![0.0; nn];
        let mut tmp = vec![0.0; nn];
        let mut trace = Vec::with_capacity(horizon);
        for _ in 0..horizon {
            stop.check()?;
            p.k1.left_mul(&law, &mut arrive);
            next_s.iter_mut().for_each(|x| *x = 0.0);
            for f in 0..n {
                if arrive[f] != 0.0 {
                    for (x, &pv) in next_s[f * nn..(f + 1) * nn].iter_mut().zip(pbar.as_slice()) {
                        *x = arrive[f] * pv;
                    }
                }
            }
            for e in 0..n {
                if law[e] == 0.0 {
                    continue;
                }
                // m = A S(e) A' + L(e) Q, column-major.
                let se = &s[e * nn..(e + 1) * nn];
                for c in 0..nx {
                    for r in 0..nx {
                        tmp[c * nx + r] = (0..nx).map(|k| a[(r, k)] * se[c * nx + k]).sum();
                    }
                }
                for c in 0..nx {
                    for r in 0..nx {
                        m[c * nx + r] = (0..nx).map(|k| tmp[k * nx + r] * a[(c, k)]).sum::<f64>()
                            + law[e] * q[(r, c)];
                    }
                }
                for (f, v) in p.k0.row(e) {
                    for (x, &mv) in next_s[f * nn..(f + 1) * nn].iter_mut().zip(&m) {
                        *x += v * mv;
                    }
                }
            }
            p.k0.left_mul(&law, &mut next_law);
            for (x, &y) in next_law.iter_mut().zip(&arrive) {
                *x += y;
            }
            std::mem::swap(&mut law, &mut next_law);
            std::mem::swap(&mut s, &mut next_s);
            let tr: f64 = (0..n)
                .filter(|&e| law[e] != 0.0)
                .map(|e| (0..nx).map(|k| s[e * nn + k * nx + k]).sum::<f64>())
                .sum();
            trace.push(if tr.is_finite() { tr } else { f64::INFINITY });
        }
        let mut j = Vec::with_capacity(horizon);
        let mut acc = 0.0;
        for (k, &t) in trace.iter().enumerate() {
            acc += t;
            j.push(acc / (k + 1) as f64);
        }
        Ok((trace, j))
    }

    /// The automaton: labels, K0 and K1 as COO.
    pub fn automaton(&self) -> AutomatonExport {
        AutomatonExport {
            labels: self.product.labels(),
            k0: self.product.k0.coo(),
            k1: self.product.k1.coo(),
        }
    }
}

fn check_work(steps: usize, per_step: usize, arg: &str) -> Result<()> {
    let work = steps as u128 * per_step.max(1) as u128;
    if work > MAX_WORK {
        return Err(Error::TooLarge {
            arg: arg.into(),
            requested: work,
            limit: MAX_WORK,
        });
    }
    Ok(())
}

/// A system, a channel, a schedule and an attacker: every quantity of the engine for them.
///
/// ```
/// use fakeack::{Attack, Attacker, Channel, LinearSystem, OnlineDesign, PowerSchedule, Scenario};
///
/// let system = LinearSystem::scalar(1.2, 0.7, 0.8, 0.8)?;
/// let design = OnlineDesign::fixed(2)?;
/// let s = Scenario::new(
///     system.clone(),
///     Channel::bernoulli(0.5)?,
///     PowerSchedule::Online(design),
///     Attacker::attack(Attack::periodic(1, 5)?),
/// )?;
/// let j = system.j_attack(0.5, design, &Attack::periodic(1, 5)?)?;
/// assert!((s.cost()? - j).abs() < 1e-12 * j);
/// # Ok::<(), fakeack::Error>(())
/// ```
#[derive(Debug)]
pub struct Scenario {
    system: LinearSystem,
    engine: Engine,
}

impl Scenario {
    /// Builds the scenario's automaton (at most [`DEFAULT_MAX_STATES`] states).
    pub fn new(
        system: LinearSystem,
        channel: Channel,
        schedule: PowerSchedule,
        attack: Attacker,
    ) -> Result<Self> {
        Self::with_max_states(system, channel, schedule, attack, DEFAULT_MAX_STATES)
    }

    /// [`Scenario::new`] with a limit on the automaton's states.
    pub fn with_max_states(
        system: LinearSystem,
        channel: Channel,
        schedule: PowerSchedule,
        attack: Attacker,
        max_states: usize,
    ) -> Result<Self> {
        let engine = Engine::new(&channel, &schedule, &attack, max_states)?;
        Ok(Scenario { system, engine })
    }

    /// The engine.
    pub fn engine(&self) -> &Engine {
        &self.engine
    }

    /// The system.
    pub fn system(&self) -> &LinearSystem {
        &self.system
    }

    /// J; +inf when unstable.
    pub fn cost(&self) -> Result<f64> {
        self.engine.cost(&self.system)
    }

    /// ρ(K0) ρ(A)².
    pub fn stability_index(&self) -> Result<f64> {
        self.engine.stability_index(&self.system)
    }

    /// Long-run fraction of high-power steps.
    pub fn high_power_rate(&self) -> Result<f64> {
        self.engine.high_power_rate()
    }

    /// Long-run flag-ACK rates.
    pub fn flag_rates(&self) -> Result<FlagRates> {
        self.engine.flag_rates()
    }

    /// P(τ = 0..n-1) and P(τ >= n).
    pub fn holding_time_law(&self, n: usize) -> Result<Vec<f64>> {
        self.engine.holding_time_law(n)
    }

    /// E Tr P_k and J_k, k = 1..=horizon.
    pub fn cost_curve(&self, horizon: usize) -> Result<(Vec<f64>, Vec<f64>)> {
        self.engine.cost_curve(&self.system, horizon)
    }
}
