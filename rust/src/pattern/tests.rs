//! Tests of the renewal form against the structured chain and closed forms.

use super::*;
use crate::chain::AttackChain;
use crate::stationary;

fn fixed(z0: u64) -> OnlineDesign {
    OnlineDesign::fixed(z0).unwrap()
}

fn wtr(lam: f64, n: usize) -> Vec<f64> {
    (0..=n)
        .map(|i| (1.0 - lam).powi(i as i32) * (1.0 + 1.3f64.powi(i as i32)))
        .collect()
}

#[test]
fn first_r_matches_structured_chain() {
    for &(lam, z0, r, t) in &[
        (0.5, 2u64, 1usize, 3usize),
        (0.3, 3, 4, 7),
        (0.8, 1, 0, 5),
        (0.6, 2, 6, 13),
    ] {
        let w = wtr(lam, 200);
        let seg = Segments::new(&w, lam, fixed(z0), r as u64).unwrap();
        let chain = AttackChain::new(lam, z0, r as u64, t as u64).unwrap();
        let expect = stationary::j_attack(&chain, &w).unwrap();
        let got = seg.j_first_r(r, t);
        assert!((got - expect).abs() < 1e-13 * expect, "{got} vs {expect}");
        let mask: Vec<bool> = (0..t).map(|i| i < r).collect();
        let via_mask = seg.j_mask(&mask).unwrap();
        assert!((via_mask - expect).abs() < 1e-13 * expect);
    }
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
