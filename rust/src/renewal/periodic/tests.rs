//! Tests of the renewal form against closed forms. Its check against the structured chain is in
//! `chain::stationary`'s tests, since the chain's solver already builds on this module.

use super::*;

fn fixed(z0: u64) -> OnlineDesign {
    OnlineDesign::fixed(z0).unwrap()
}

fn wtr(lam: f64, n: usize) -> Vec<f64> {
    (0..=n)
        .map(|i| (1.0 - lam).powi(i as i32) * (1.0 + 1.3f64.powi(i as i32)))
        .collect()
}

#[test]
fn mass_per_tau_is_one_when_all_blocked() {
    // Σ_k M_k over all segments = Σ_τ a^τ = 1/λ for any μ.
    for &mu in &[1.0, 0.4, 0.0] {
        let lam = 0.3;
        let d = OnlineDesign::new(2, mu).unwrap();
        let seg = Segments::new(&wtr(lam, 2000), lam, d, 600).unwrap();
        let total: f64 = seg.m.iter().sum();
        assert!((total - 1.0 / lam).abs() < 1e-10, "{mu}: {total}");
    }
}

#[test]
fn overflowing_traces_give_inf_not_nan() {
    // Weighted traces that overflow from τ = 3 on: every segment reaching them is +inf.
    let w = vec![
        1.0,
        2.0,
        4.0,
        f64::INFINITY,
        f64::INFINITY,
        f64::INFINITY,
        1.0,
    ];
    for mu in [1.0, 0.5] {
        let seg = Segments::new(&w, 0.5, OnlineDesign::new(1, mu).unwrap(), 2).unwrap();
        assert!(seg.w.iter().all(|x| !x.is_nan()), "{:?}", seg.w);
        assert_eq!(seg.w[2], f64::INFINITY);
        assert_eq!(seg.j_first_r(2, 3), f64::INFINITY);
        // Segment 0 never reaches the overflow: J without attack stays finite.
        assert!(seg.j_first_r(0, 3).is_finite());
    }
    // Segment 0 itself beyond the double range: J is +inf, not 0 * inf or inf - inf.
    let w = vec![f64::INFINITY; 8];
    for mu in [1.0, 0.0] {
        let seg = Segments::new(&w, 0.5, OnlineDesign::new(1, mu).unwrap(), 2).unwrap();
        assert_eq!(seg.j_first_r(0, 1), f64::INFINITY);
        assert_eq!(seg.j_first_r(2, 5), f64::INFINITY);
    }
}

#[test]
fn flag_rates_match_online_rate() {
    // No attack: delivered = sent = the online high-power rate (Model note 2).
    for &(lam, z0, mu) in &[(0.5, 2u64, 1.0), (0.3, 3, 0.4), (0.8, 1, 0.0)] {
        let d = OnlineDesign::new(z0, mu).unwrap();
        let seg = Segments::new(&wtr(lam, 50), lam, d, 2).unwrap();
        let (sent, delivered) = seg.flag_rates(&[false, false, false]).unwrap();
        let expect = d.high_power_rate(lam).unwrap();
        assert!((sent - expect).abs() < 1e-14 && (delivered - expect).abs() < 1e-14);
    }
}

/// The one-vector, allocating form that the two-vector pass replaced.
fn segment_sums_reference(v: &[f64], z0: u64, mu: f64, kmax: u64) -> Vec<f64> {
    let z = z0 as usize;
    let pre = prefix(v);
    let zsum = |s: usize, k: usize| {
        let first = if k == 0 { s } else { s + 1 };
        pre[s + z + 1] - pre[first] + (1.0 - mu) * v[s + z + 1]
    };
    let mut out = Vec::new();
    let mut binom = vec![1.0];
    for k in 0..=kmax as usize {
        let total: f64 = binom
            .iter()
            .enumerate()
            .map(|(i, b)| {
                if *b == 0.0 {
                    0.0
                } else {
                    b * zsum(k * z + i, k)
                }
            })
            .sum();
        out.push(total);
        let mut next = vec![0.0; binom.len() + 1];
        for (i, b) in binom.iter().enumerate() {
            next[i] += mu * b;
            next[i + 1] += (1.0 - mu) * b;
        }
        binom = next;
    }
    out
}

#[test]
fn one_pass_segment_sums_keep_every_bit() {
    for &mu in &[1.0, 0.0, 0.3, 0.5672848311935325, 0.999] {
        for &(lam, z0, kmax) in &[(0.5, 2u64, 59u64), (0.3, 5, 40), (0.8, 1, 100)] {
            let n = tau_needed(z0, kmax) as usize + 1;
            let w = wtr(lam, n);
            let m: Vec<f64> = (0..n).map(|i| (1.0 - lam).powi(i as i32)).collect();
            let (sw, sm) = segment_sums(&w, &m, z0, mu, kmax);
            let (rw, rm) = (
                segment_sums_reference(&w, z0, mu, kmax),
                segment_sums_reference(&m, z0, mu, kmax),
            );
            let bits = |x: &[f64]| x.iter().map(|y| y.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&sw), bits(&rw), "mu={mu} z0={z0}");
            assert_eq!(bits(&sm), bits(&rm), "mu={mu} z0={z0}");
        }
    }
}

/// `of_walk_with_masses` needs (z0 + 1)(kmax + 1) + 1 weighted traces and as many masses, and reads
/// only those of longer tables (kills the length check's `||` turned `&&`, and `mass.len() <
/// need` turned `>`).
#[test]
fn segments_need_enough_traces_and_masses() {
    let (lam, z0, kmax) = (0.4, 2u64, 3u64);
    let walk = Walk::new(lam, fixed(z0), 0.0).unwrap();
    let need = ((z0 + 1) * (kmax + 1) + 1) as usize;
    let w = wtr(lam, need + 5);
    let mass = masses(&walk, need + 6);
    let long = Segments::of_walk_with_masses(&w, &mass, &walk, kmax).unwrap();
    let exact = Segments::of_walk_with_masses(&w[..need], &mass[..need], &walk, kmax).unwrap();
    assert_eq!((&long.w, &long.m), (&exact.w, &exact.m));
    assert!(Segments::of_walk_with_masses(&w[..need - 1], &mass, &walk, kmax).is_err());
    assert!(Segments::of_walk_with_masses(&w, &mass[..need - 1], &walk, kmax).is_err());
}

/// Only mixed memories (μ < 1) are limited to `MAX_SEGMENTS_MIXED` segments, the limit itself
/// allowed (kills `mu < 1.0` turned `<=` and `kmax > MAX_SEGMENTS_MIXED` turned `>=`).
#[test]
fn mixed_memory_depth_limit_is_inclusive() {
    let mixed = OnlineDesign::new(2, 0.5).unwrap();
    assert!(Segments::check_depth(mixed, MAX_SEGMENTS_MIXED).is_ok());
    assert!(Segments::check_depth(mixed, MAX_SEGMENTS_MIXED + 1).is_err());
    assert!(Segments::check_depth(fixed(2), MAX_SEGMENTS_MIXED + 1).is_ok());
}

/// Segments built up to kmax answer first-r-of-t attacks with r <= kmax and refuse deeper ones
/// (kills `check_holds` returning Ok, which would read past the table).
#[test]
fn first_r_attack_needs_its_segments() {
    let (lam, z0) = (0.5, 2u64);
    let w = wtr(lam, 200);
    let seg = Segments::new(&w, lam, fixed(z0), 2).unwrap();
    let within = Attack::periodic(2, 5).unwrap();
    assert_eq!(seg.j_attack(&within).unwrap(), seg.j_first_r(2, 5));
    let deeper = Attack::periodic(3, 7).unwrap();
    assert!(matches!(
        seg.j_attack(&deeper),
        Err(Error::InvalidArgument { .. })
    ));
}

/// The worst mask is the one of largest J among all masks with `blocked` of `t` flags blocked
/// (every t-bit word counted out here), it has that J, and the third value is the consecutive
/// mask's J from the closed form. Besides traces of the usual shape (where blocking
/// consecutively is worst), weights that make segment 1 heavy and deeper ones light, so that
/// spreading the blocked flags is worse (kills `worst_mask` returning a constant, and a search
/// that never moves off the consecutive mask, as with `best_j * (1 + 1e-12)` turned `+`).
#[test]
fn worst_mask_attains_the_exhaustive_maximum() {
    let (lam, z0) = (0.5, 2u64);
    // J below 1 here, so that an absolute tolerance of 1 in place of the relative 1e-12 would
    // never move off the consecutive mask.
    let mut hot = vec![0.01; 200];
    hot[2..=4].fill(0.5);
    for (w, spread) in [(wtr(lam, 400), false), (hot, true)] {
        let seg = Segments::new(&w, lam, fixed(z0), 8).unwrap();
        for (t, blocked) in [(5usize, 2usize), (7, 3), (6, 0), (9, 8)] {
            let (mask, j, j_consecutive) = worst_mask(&seg, t, blocked).unwrap();
            assert_eq!(mask.len(), t);
            assert_eq!(mask.iter().filter(|&&b| b).count(), blocked);
            assert_eq!(seg.j_mask(&mask).unwrap(), j);
            let best = (0u32..1 << t)
                .filter(|b| b.count_ones() as usize == blocked)
                .map(|b| {
                    let m: Vec<bool> = (0..t).map(|i| b >> i & 1 == 1).collect();
                    seg.j_mask(&m).unwrap()
                })
                .fold(f64::NEG_INFINITY, f64::max);
            assert!(j >= best * (1.0 - 1e-12), "{t} {blocked}: {j} vs {best}");
            let closed = seg.j_first_r(blocked, t);
            assert!((j_consecutive - closed).abs() < 1e-12 * closed);
            if spread && (t, blocked) == (5, 2) {
                assert_eq!(mask, [true, false, true, false, false]);
                assert!(j > j_consecutive * 1.01);
            }
        }
    }
}

/// With forged flags a segment k weighs ε^k, ε = 1 / (1 - γ); where k ln ε passes 700 the
/// product is taken in logarithms. Checked against 10^(k log10 ε - 300) for values 1e-300,
/// γ the largest double below 1 (ln ε ≈ 36.7, so k >= 20 takes that branch; kills its `+`
/// turned `-`).
#[test]
fn block_factor_scaling_survives_large_powers() {
    let walk = Walk::new(0.5, fixed(1), 1.0 - f64::EPSILON / 2.0).unwrap();
    let ln_eps = walk.ln_block_factor();
    assert!(ln_eps > 35.0);
    let mut v = vec![1e-300; 30];
    scale_by_block_factor(&mut v, &walk);
    for (k, x) in v.iter().enumerate() {
        let want = 10f64.powf(k as f64 * ln_eps / std::f64::consts::LN_10 - 300.0);
        assert!((x - want).abs() < 1e-11 * want, "{k}: {x} vs {want}");
    }
}

/// With μ = 1 a segment has no long interval: a trace beyond the double range just past the
/// segment leaves it finite (kills `one_mu > 0.0` turned `>=`, which makes 0 · inf = NaN, hence
/// +inf). Segment 0 of z0 = 2 is v[0] + v[1] + v[2].
#[test]
fn a_fixed_memory_ignores_the_trace_past_its_segment() {
    let v = [
        1.0,
        2.0,
        3.0,
        f64::INFINITY,
        f64::INFINITY,
        f64::INFINITY,
        1.0,
    ];
    let (w, _) = segment_sums(&v, &v, 2, 1.0, 0);
    assert_eq!(w, vec![6.0]);
}

/// The large-period limit takes β in [0, 1] only, and at β = 0 is the unattacked J of the
/// closed form, (t W_0) / (t M_0) (kills the range check's `&&` turned `||` and W_0 / M_0
/// turned `%`).
#[test]
fn large_period_limit_checks_beta_and_starts_unattacked() {
    let (lam, z0) = (0.5, 2u64);
    let w = wtr(lam, 200);
    let seg = Segments::new(&w, lam, fixed(z0), 4).unwrap();
    let j_max = 100.0;
    let at_zero = j_limit(&seg, lam, j_max, 0.0).unwrap();
    let unattacked = seg.j_first_r(0, 7);
    assert!(
        (at_zero - unattacked).abs() < 1e-14 * unattacked,
        "{at_zero} vs {unattacked}"
    );
    for beta in [1.5, -0.1, f64::NAN, f64::INFINITY] {
        assert!(j_limit(&seg, lam, j_max, beta).is_err(), "{beta}");
    }
    assert!(j_limit(&seg, lam, j_max, 1.0).is_ok());
}

/// The threshold of the large-period limit is 0 when the online schedule does not beat the
/// reference even unattacked (J_ref <= J_on), whatever J_max, and 1 when even J_max does not
/// exceed the reference; between, the limit J(β̄) equals the reference (kills the first test's
/// `||` turned `&&`).
#[test]
fn large_period_threshold_at_its_ends() {
    let (lam, z0) = (0.5, 2u64);
    let w = wtr(lam, 200);
    let seg = Segments::new(&w, lam, fixed(z0), 4).unwrap();
    let j_on = seg.j_first_r(0, 1);
    let j_max = 3.0 * j_on;
    assert_eq!(beta_limit_threshold(&seg, lam, j_max, 0.9 * j_on), 0.0);
    assert_eq!(
        beta_limit_threshold(&seg, lam, f64::INFINITY, 2.0 * j_on),
        0.0
    );
    assert_eq!(beta_limit_threshold(&seg, lam, j_max, 4.0 * j_on), 1.0);
    let j_ref = 2.0 * j_on;
    let bar = beta_limit_threshold(&seg, lam, j_max, j_ref);
    assert!(0.0 < bar && bar < 1.0);
    let at = j_limit(&seg, lam, j_max, bar).unwrap();
    assert!((at - j_ref).abs() < 1e-12 * j_ref, "{at} vs {j_ref}");
}

/// Below e^700 the block factor multiplies directly: with γ = 1/2 (ε = 2) and values 1e-300,
/// x ε^k = x 2^k is a double, and the direct product of the first twenty stays within 1e-14 of
/// it, where the logarithmic route, exp(ln x + k ln 2), loses about |ln x| ulps (kills the branch's
/// `f < 700` turned `==`, which sends every product the long way).
#[test]
fn block_factor_scaling_is_direct_below_the_overflow() {
    let walk = Walk::new(0.5, fixed(1), 0.5).unwrap();
    let mut v = vec![1e-300; 20];
    scale_by_block_factor(&mut v, &walk);
    for (k, x) in v.iter().enumerate() {
        let want = 1e-300 * 2f64.powi(k as i32);
        assert!((x - want).abs() <= 1e-14 * want, "{k}: {x:e} vs {want:e}");
    }
}
