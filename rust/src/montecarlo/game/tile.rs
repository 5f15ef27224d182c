//! The lock-step kernel: a tile of [`LANES`] runs advanced step by step, their window tests and
//! mode switches (the CUSUM's, at every step, within the step loop).

use super::plan::*;
use super::*;
use crate::montecarlo::automaton::tables::Aliases;

/// The state of a tile's runs.
pub(super) struct Tile {
    pub(super) rng: [Xoshiro256pp; LANES],
    pub(super) tau: [usize; LANES],
    /// The channel state c_k of the coming step (0 on the i.i.d. channel).
    pub(super) chan: [usize; LANES],
    pub(super) z: [u64; LANES],
    /// The attacker's state: the blocking counter, or the automaton's state.
    pub(super) sigma: [u64; LANES],
    pub(super) pending: [bool; LANES],
    pub(super) flagged: [bool; LANES],
    pub(super) gap: [usize; LANES],
    /// Online since the last flag-ACK that reached the sensor (the run's start counts as one):
    /// the next gap is checked by the support check.
    pub(super) armed: [bool; LANES],
    /// The current window had a gap shorter than the support check's `min_gap`.
    pub(super) short: [bool; LANES],
    pub(super) online: [bool; LANES],
    /// Windows (steps, for the CUSUM) left offline.
    pub(super) left: [u64; LANES],
    /// The CUSUM statistic W, or the likelihood-ratio test's Λ.
    pub(super) stat: [f64; LANES],
    /// The CUSUM or Λ runs (online and not dormant).
    pub(super) watching: [bool; LANES],
    pub(super) pos: [usize; LANES],
    pub(super) count: [i64; LANES],
    pub(super) bins: Vec<[u32; LANES]>,
    pub(super) cost: [f64; LANES],
    pub(super) window_cost: [f64; LANES],
    pub(super) high: [u64; LANES],
    pub(super) online_steps: [u64; LANES],
    pub(super) delivered: [u64; LANES],
    pub(super) tested: [u64; LANES],
    pub(super) alarms: [u64; LANES],
    pub(super) fallbacks: [u64; LANES],
}

impl Tile {
    pub(super) fn new(plan: &Plan<'_>, index: u64) -> Self {
        let mut sm = SplitMix64::stream(plan.cfg.seed, index);
        let mut rng: [Xoshiro256pp; LANES] =
            std::array::from_fn(|_| Xoshiro256pp::from_splitmix(&mut sm));
        // c_1 from the stationary law, one output of each lane's stream (none on the i.i.d.
        // channel, whose streams are as they always were).
        let chan = std::array::from_fn(|l| {
            plan.channel
                .as_ref()
                .map_or(0, |ch| ch.init.draw(rng[l].next_u64()))
        });
        let offline = matches!(plan.cfg.policy, Policy::Offline);
        // An automaton starts in its start state, a blocking counter at 0.
        let sigma = match plan.block {
            Block::Automaton { start, .. } => start,
            _ => 0,
        };
        Tile {
            rng,
            tau: [0; LANES],
            chan,
            z: [0; LANES],
            sigma: [sigma; LANES],
            // The paper's initial condition: high power at k = 1, as after a flag-ACK.
            pending: [true; LANES],
            flagged: [false; LANES],
            gap: [0; LANES],
            armed: [!offline; LANES],
            short: [false; LANES],
            online: [!offline; LANES],
            left: [0; LANES],
            // W = 0 at the initial condition, as after a flag-ACK at step 0; the likelihood-ratio
            // test's first window opens at y = 1.
            stat: [match &plan.cfg.policy {
                Policy::Test {
                    detector: Detector::Likelihood { opening, .. },
                    ..
                } => opening[0],
                _ => 0.0,
            }; LANES],
            watching: [true; LANES],
            pos: [0; LANES],
            count: [0; LANES],
            bins: vec![[0; LANES]; plan.bins],
            cost: [0.0; LANES],
            window_cost: [0.0; LANES],
            high: [0; LANES],
            online_steps: [0; LANES],
            delivered: [0; LANES],
            tested: [0; LANES],
            alarms: [0; LANES],
            fallbacks: [0; LANES],
        }
    }

    /// `steps` steps of every lane, by the kernel instantiated for the plan's features.
    pub(super) fn advance(&mut self, plan: &Plan<'_>, steps: u64) {
        let mu = plan.cfg.design.mu < 1.0;
        let det = if matches!(plan.cfg.policy, Policy::Cusum { .. }) {
            DET_CUSUM
        } else if plan.likelihood() {
            DET_LR
        } else if plan.bins > 0 {
            DET_BINS
        } else {
            DET_NONE
        };
        macro_rules! det {
            ($mu:literal, $forge:literal, $rule:expr, $ch:literal) => {
                match det {
                    DET_NONE => self.kernel::<$mu, $forge, DET_NONE, { $rule }, $ch>(plan, steps),
                    DET_BINS => self.kernel::<$mu, $forge, DET_BINS, { $rule }, $ch>(plan, steps),
                    DET_LR => self.kernel::<$mu, $forge, DET_LR, { $rule }, $ch>(plan, steps),
                    _ => self.kernel::<$mu, $forge, DET_CUSUM, { $rule }, $ch>(plan, steps),
                }
            };
        }
        macro_rules! go {
            ($rule:expr) => {
                match (mu, plan.forging) {
                    // A Markov channel: the memory-length and forgery draws always run (μ = 1
                    // and γ = 0 draw sure outcomes), which halves the instantiations.
                    _ if plan.channel.is_some() => det!(true, true, $rule, true),
                    (false, false) => det!(false, false, $rule, false),
                    (false, true) => det!(false, true, $rule, false),
                    (true, false) => det!(true, false, $rule, false),
                    (true, true) => det!(true, true, $rule, false),
                }
            };
        }
        const A: u8 = RULE_AUTOMATON;
        match plan.block {
            Block::None => go!(RULE_NONE),
            Block::FirstR { .. } => go!(RULE_FIRST_R),
            Block::Mask(_) => go!(RULE_MASK),
            Block::Random(_) => go!(RULE_RANDOM),
            // An automaton forges by its own moves (the plan's γ is 0), so FORGE is off.
            Block::Automaton { .. } => match mu {
                _ if plan.channel.is_some() => det!(true, false, A, true),
                false => det!(false, false, A, false),
                true => det!(true, false, A, false),
            },
        }
    }

    /// The step loop, branch-free except for the rare ties of the Bernoulli slices (and an
    /// automaton's alias draw): `MU` (a memory-length draw), `FORGE` (forged flags), `DET` (the
    /// interval test's histogram, or the CUSUM with its alarms and fall-backs at any step, or
    /// neither) and `RULE` (the attacker's blocking rule, or its automaton) are
    /// compile-time, so each plan runs only its code; so is `CH`, a Markov channel (the plan's),
    /// whose state sets each arrival's probability and moves after the step by one further draw.
    #[inline(never)]
    pub(super) fn kernel<
        const MU: bool,
        const FORGE: bool,
        const DET: u8,
        const RULE: u8,
        const CH: bool,
    >(
        &mut self,
        plan: &Plan<'_>,
        steps: u64,
    ) {
        let offline = &plan.cfg.offline[..];
        let period = offline.len();
        let traces = &plan.traces[..];
        let last = traces.len() - 1;
        let bin_of = &plan.bin_of[..];
        let gap_last = bin_of.len().saturating_sub(1);
        let z0 = plan.z0;
        // 0 without the support check, so no gap is short.
        let min_gap = plan.min_gap;
        let support = min_gap > 1;
        let (first_r, period_t, mask): (u64, u64, &[bool]) = match &plan.block {
            Block::FirstR { r, t } => (*r, *t, &[]),
            Block::Mask(m) => (0, m.len() as u64, &m[..]),
            _ => (0, 1, &[]),
        };
        let beta = match plan.block {
            Block::Random(b) => b,
            _ => Bern::new(0.0),
        };
        let no_moves = Aliases::default();
        let moves = match &plan.block {
            Block::Automaton { moves, .. } => moves,
            _ => &no_moves,
        };
        let channel = plan.channel.as_ref().filter(|_| CH);
        let (inc_flag, inc_quiet, threshold): (&[f64], &[f64], f64) = match &plan.cfg.policy {
            Policy::Cusum {
                inc_flag,
                inc_quiet,
                threshold,
                ..
            } => (inc_flag, inc_quiet, *threshold),
            Policy::Test {
                detector:
                    Detector::Likelihood {
                        inc_flag,
                        inc_quiet,
                        ..
                    },
                ..
            } => (inc_flag, inc_quiet, 0.0),
            _ => (&[], &[], 0.0),
        };
        let fall_steps = plan.fall_steps;
        for _ in 0..steps {
            for l in 0..LANES {
                let rng = &mut self.rng[l];
                let w = rng.next_u64();
                let online = self.online[l];
                let pos = self.pos[l];
                let high = (online & self.pending[l]) | (!online & (offline[pos] != 0));
                let next_pos = pos + 1;
                self.pos[l] = if online | (next_pos == period) {
                    0
                } else {
                    next_pos
                };
                let arrive = match channel {
                    // The state's arrival draw for the step's power: a high-power packet too
                    // may be lost.
                    Some(ch) => {
                        ch.arrive[2 * self.chan[l] + usize::from(high)].draw(w & 0xffff, rng)
                    }
                    None => high | plan.lam.draw(w & 0xffff, rng),
                };
                // Masks instead of selects: the outcomes are coin flips, and a mispredicted branch
                // costs more than the whole step. `black_box` keeps LLVM from turning the
                // masked arithmetic back into branches.
                let keep = black_box(usize::from(!arrive).wrapping_neg()); // ones iff no arrival
                let tau = (self.tau[l] + 1) & keep;
                self.tau[l] = tau;
                self.window_cost[l] += traces[tau.min(last)];
                self.high[l] += u64::from(high);
                self.online_steps[l] += u64::from(online);
                let reset = black_box(u64::from(self.flagged[l]).wrapping_neg()); // ones iff flagged
                let z = (((self.z[l] + 1) & !reset) | (reset & 1)) & (keep as u64);
                self.z[l] = z;
                let mu_draw = if MU {
                    plan.mu.draw((w >> 16) & 0xffff, rng)
                } else {
                    true
                };
                let flag = (z > z0) | ((z == z0) & mu_draw);
                let sigma = self.sigma[l];
                let blocked = match RULE {
                    RULE_FIRST_R => sigma < first_r,
                    RULE_MASK => mask[sigma as usize],
                    RULE_RANDOM => beta.draw((w >> 32) & 0xffff, rng),
                    _ => false,
                };
                if RULE == RULE_FIRST_R || RULE == RULE_MASK {
                    let next = sigma + u64::from(flag);
                    self.sigma[l] = if next == period_t { 0 } else { next };
                }
                let delivered = if RULE == RULE_AUTOMATON {
                    // The automaton's move on the step's event, from a fresh output.
                    let event = 2 * sigma as usize + usize::from(flag);
                    let o = moves.draw(event, rng.next_u64());
                    self.sigma[l] = o >> 1;
                    o & 1 != 0
                } else {
                    let forged = FORGE & !flag & plan.gamma.draw(w >> 48, rng);
                    (flag & !blocked) | forged
                };
                self.flagged[l] = flag;
                self.pending[l] = delivered;
                let gap = self.gap[l] + 1;
                self.delivered[l] += u64::from(delivered);
                let counted = delivered & online;
                self.count[l] += i64::from(counted);
                if DET == DET_BINS {
                    self.bins[bin_of[gap.min(gap_last)] as usize][l] += u32::from(counted);
                }
                if support {
                    // Offline the lane is disarmed, so `counted` alone re-arms it.
                    self.short[l] |= counted & self.armed[l] & ((gap as u64) < min_gap);
                    self.armed[l] |= counted;
                }
                self.gap[l] = gap & black_box(usize::from(!delivered).wrapping_neg());
                if DET == DET_CUSUM {
                    if !online {
                        self.left[l] -= 1;
                        self.online[l] = self.left[l] == 0;
                    } else if self.watching[l] {
                        // y = `gap`, the steps since the last flag-ACK that reached the sensor.
                        let y = gap.min(inc_flag.len()) - 1;
                        let inc = if delivered { inc_flag[y] } else { inc_quiet[y] };
                        // W is finite, so W + inc is never NaN; -inf gives 0, +inf an alarm.
                        let w = (self.stat[l] + inc).max(0.0);
                        self.tested[l] += 1;
                        if w >= threshold {
                            self.alarms[l] += 1;
                            self.fallbacks[l] += 1;
                            self.stat[l] = 0.0;
                            self.watching[l] = false;
                            // The offline stretch starts next step, at the period's start
                            // (`pos` is 0 after an online step).
                            self.online[l] = fall_steps == 0;
                            self.left[l] = fall_steps;
                        } else {
                            self.stat[l] = w;
                        }
                    } else {
                        // Dormant: the first flag-ACK back online restarts the statistic, with
                        // y = 1 on the next step.
                        self.watching[l] = delivered;
                    }
                }
                if DET == DET_LR && online {
                    if self.watching[l] {
                        let y = gap.min(inc_flag.len()) - 1;
                        let inc = if delivered { inc_flag[y] } else { inc_quiet[y] };
                        // +inf (an outcome impossible without attack) decides the window, even
                        // after a -inf, so Λ is never NaN.
                        let stat = self.stat[l];
                        self.stat[l] = if inc == f64::INFINITY || stat == f64::INFINITY {
                            f64::INFINITY
                        } else {
                            stat + inc
                        };
                    } else {
                        // Dormant back online: the first flag-ACK starts Λ, with y = 1 next step.
                        self.watching[l] = delivered;
                    }
                }
                if let Some(ch) = channel {
                    // c_k -> c_{k+1}, from a fresh output of the lane's stream.
                    let rng = &mut self.rng[l];
                    self.chan[l] = ch.rows[self.chan[l]].draw(rng.next_u64());
                }
            }
        }
    }

    /// The end of a window: the online lanes' tests and the mode switches; the window's test is
    /// counted in the results when `counted` (it ends after the burn-in).
    pub(super) fn end_window(&mut self, plan: &Plan<'_>, counted: bool) {
        let c = u64::from(counted);
        for l in 0..LANES {
            self.cost[l] += self.window_cost[l];
            self.window_cost[l] = 0.0;
            if let Policy::Test {
                detector,
                harmful_at_most,
                fallback,
                ..
            } = &plan.cfg.policy
            {
                if self.online[l] {
                    let n = self.count[l];
                    let alarm = match detector {
                        Detector::Count { lo, hi } => n <= *lo || n >= *hi,
                        Detector::Likelihood { critical, .. } => self.stat[l] >= *critical,
                        Detector::Interval {
                            expected, critical, ..
                        } => {
                            let x2: f64 = expected
                                .iter()
                                .zip(&self.bins)
                                .map(|(e, o)| {
                                    let d = f64::from(o[l]) - e;
                                    d * d / e
                                })
                                .sum();
                            x2 > *critical
                        }
                    };
                    // The support check.
                    let alarm = alarm || self.short[l];
                    self.tested[l] += c;
                    self.alarms[l] += c * u64::from(alarm);
                    if alarm && harmful_at_most.is_none_or(|b| n <= b) {
                        self.fallbacks[l] += c;
                        if *fallback > 0 {
                            self.online[l] = false;
                            // The first gap back online is not checked.
                            self.armed[l] = false;
                            self.left[l] = *fallback;
                            self.pos[l] = 0;
                        }
                    }
                } else {
                    self.left[l] -= 1;
                    if self.left[l] == 0 {
                        self.online[l] = true;
                    }
                }
            }
            if let Policy::Test {
                detector:
                    Detector::Likelihood {
                        inc_quiet, opening, ..
                    },
                ..
            } = &plan.cfg.policy
            {
                // Offline the statistic is dormant; online the next window opens at its gap.
                self.watching[l] &= self.online[l];
                self.stat[l] = if self.watching[l] {
                    opening_at(opening, inc_quiet, self.gap[l] + 1)
                } else {
                    0.0
                };
            }
            self.count[l] = 0;
            self.short[l] = false;
            for b in &mut self.bins {
                b[l] = 0;
            }
        }
    }

    /// Forgets the costs and rates the burn-in accumulated (the current window's flags stay: its
    /// test reads the whole window), and the CUSUM's alarms, which come at steps.
    pub(super) fn start_measuring(&mut self, plan: &Plan<'_>) {
        if matches!(plan.cfg.policy, Policy::Cusum { .. }) {
            self.tested = [0; LANES];
            self.alarms = [0; LANES];
            self.fallbacks = [0; LANES];
        }
        self.cost = [0.0; LANES];
        self.window_cost = [0.0; LANES];
        self.high = [0; LANES];
        self.online_steps = [0; LANES];
        self.delivered = [0; LANES];
    }
}

/// The likelihood-ratio test's opening at the window's first gap y >= 1: the table up to its
/// length Y, then one more last quiet increment per step (an infinite opening stays).
fn opening_at(opening: &[f64], inc_quiet: &[f64], y: usize) -> f64 {
    let t = opening.len();
    if y <= t {
        return opening[y - 1];
    }
    let (o, q) = (opening[t - 1], inc_quiet[t - 1]);
    if !o.is_finite() || q == 0.0 {
        o
    } else {
        o + (y - t) as f64 * q
    }
}

pub(super) fn run_tile(plan: &Plan<'_>, index: u64, cancel: &AtomicBool) -> Result<Tile> {
    let cfg = plan.cfg;
    let mut tile = Tile::new(plan, index);
    let chunked = |tile: &mut Tile, steps: u64| -> Result<()> {
        let mut left = steps;
        while left > 0 {
            if cancel.load(Ordering::Relaxed) {
                return Err(Error::Interrupted);
            }
            let n = left.min(CHECK_STEPS);
            tile.advance(plan, n);
            left -= n;
        }
        Ok(())
    };
    // Windows run from the first step; the measurement starts after the burn-in, which may end
    // inside a window.
    let total = cfg.burn_in + cfg.horizon;
    let mut at = 0u64;
    let mut measuring = cfg.burn_in == 0;
    while at < total {
        let end = (at + cfg.window).min(total);
        if !measuring && end > cfg.burn_in {
            chunked(&mut tile, cfg.burn_in - at)?;
            tile.start_measuring(plan);
            measuring = true;
            chunked(&mut tile, end - cfg.burn_in)?;
        } else {
            chunked(&mut tile, end - at)?;
        }
        if end - at == cfg.window {
            tile.end_window(plan, end > cfg.burn_in);
        } else {
            for l in 0..LANES {
                tile.cost[l] += tile.window_cost[l];
            }
        }
        at = end;
    }
    Ok(tile)
}
