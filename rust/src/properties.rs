//! Property-based tests across modules (proptest): random systems up to n_x = 6, λ in (0, 1),
//! z0 in 1..=8, r < t <= 60, μ in [0, 1].

use nalgebra::DMatrix;
use proptest::prelude::*;
use proptest::test_runner::RngSeed;

use crate::attack::{longest_cyclic_run, Attack};
use crate::chain::general;
use crate::chain::stationary::{balance_residual, gth, j_attack, pairwise_sum, structured};
use crate::chain::AttackChain;
use crate::renewal::periodic::Segments;
use crate::schedule::OnlineDesign;
use crate::schedule::{j_max, j_online};
use crate::system::LinearSystem;

fn system(n: usize, m: usize, entries: &[f64], scale: f64) -> Option<LinearSystem> {
    let mut it = entries.iter().cycle().copied();
    let a = DMatrix::from_fn(n, n, |_, _| it.next().unwrap_or(0.0)) * scale;
    let c = DMatrix::from_fn(m, n, |_, _| it.next().unwrap_or(0.0));
    let b = DMatrix::from_fn(n, n, |_, _| it.next().unwrap_or(0.0));
    let d = DMatrix::from_fn(m, m, |_, _| it.next().unwrap_or(0.0));
    let q = &b * b.transpose() + DMatrix::identity(n, n) * 0.1;
    let r = &d * d.transpose() + DMatrix::identity(m, m) * 0.2;
    LinearSystem::new(a, c, q, r).ok()
}

/// First-order estimate φ of the relative residual ||g̃(h(X)) - X||_F / ||X||_F that evaluating it
/// in double precision (u = 2^-53) leaves for X = P̄ rounded to double, i.e. for a perfect solver:
///
/// φ = u [ (1 + ||F||²) + ||I - KC||² (||A||_F² ||P̄||_F + ||Q||_F) / ||P̄||_F
///         + (||h(P̄)||_F + ||K||² ||S||) / ||P̄||_F ],
///
/// S = C h(P̄) C' + R, K = h(P̄) C' S^{-1}, F = (I - K C) A; 2-norms unless marked F.
///
/// Derivation. (1) X = P̄ + δ with |δ| <= u |P̄|. The derivative of X -> g̃(h(X)) at P̄ is
/// δ -> F δ F', so X's exact residual is ||F δ F' - δ||_F / ||P̄||_F <= u (1 + ||F||²).
/// (2) h(X) = A X A' + Q computed in double errs by δY with
/// ||δY||_F <= γ_{2n+1} (||A||_F² ||X||_F + ||Q||_F), γ_k ≈ k u, and g̃ passes δY on as
/// (I - K C) δY (I - K C)'. (3) Inside g̃, Y - K S K' subtracts K S K' <= Y from Y = h(P̄);
/// with a backward-stable Cholesky solve this costs O(u (||Y||_F + ||K||² ||S||)).
/// The constant 32 covers the first-order constants (the longest chain, A X A', has 2n+1 <= 13
/// roundings); the largest residual/φ seen over 120 000 draws of this generator is 5.
///
/// Why not a fixed bound: when C barely sees an unstable direction, ||I - K C|| reaches ~800 and
/// φ ~ 1e-9 in 100 000 draws; the correctly rounded exact P̄ of one of them (computed in 60-digit
/// arithmetic) evaluates to 9.7e-11, a hair under the former bound of 1e-10, and φ grows without
/// limit as C's view of that direction shrinks, so a fixed bound fails for some draw whatever the
/// solver. Before the solver's defect correction ([`crate::system::riccati::steady_state`])
/// residuals reached 1e4 φ (2.2e-7) on these draws, and this bound catches that.
fn residual_floor(sys: &LinearSystem) -> f64 {
    let (a, c, q, r, pbar) = (sys.a(), sys.c(), sys.q(), sys.r(), sys.pbar());
    let n = sys.n();
    let norm2 = |m: &DMatrix<f64>| m.singular_values().max();
    let hp = sys.h(pbar);
    let s = c * &hp * c.transpose() + r;
    let Some(s_chol) = s.clone().cholesky() else {
        return f64::INFINITY;
    };
    let gain_t = s_chol.solve(&(c * &hp)); // K'
    let i_kc = DMatrix::<f64>::identity(n, n) - gain_t.transpose() * c;
    let f = &i_kc * a;
    let p_norm = pbar.norm();
    let rounding = 1.0 + norm2(&f).powi(2);
    let lyapunov = norm2(&i_kc).powi(2) * (a.norm().powi(2) * p_norm + q.norm()) / p_norm;
    let update = (hp.norm() + norm2(&gain_t).powi(2) * norm2(&s)) / p_norm;
    f64::EPSILON / 2.0 * (rounding + lyapunov + update)
}

/// Seed of every property test when the environment variable `CI` is set (and
/// `PROPTEST_RNG_SEED` is not): CI runs the same cases every time, local runs draw new ones.
/// Failures found anywhere are kept in `rust/proptest-regressions/properties.txt` (committed) and
/// re-run first, whatever the seed.
const CI_SEED: u64 = 0x5eed_fa4e_ac4b;

/// The properties' configuration: 48 cases, seeded as [`CI_SEED`] says. `PROPTEST_CASES` and
/// `PROPTEST_RNG_SEED` still override (the long random search: README, development).
fn config() -> ProptestConfig {
    let mut config = ProptestConfig::with_cases(48);
    if let Ok(cases) = std::env::var("PROPTEST_CASES") {
        config.cases = cases.parse().unwrap_or(config.cases);
    }
    if std::env::var_os("CI").is_some() && std::env::var_os("PROPTEST_RNG_SEED").is_none() {
        config.rng_seed = RngSeed::Fixed(CI_SEED);
    }
    config
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn stationary_solvers_agree(lam in 0.01f64..0.99, z0 in 1u64..=8, t in 1u64..=60, rfrac in 0.0f64..1.0) {
        let r = ((t as f64) * rfrac) as u64 % t;
        let chain = AttackChain::new(lam, z0, r, t).unwrap();
        let fast = structured(&chain).unwrap();
        let slow = gth(&chain.build_csr().unwrap()).unwrap();
        prop_assert!(fast.iter().all(|&x| x >= 0.0));
        prop_assert!((pairwise_sum(&fast) - 1.0).abs() < 1e-12);
        for (x, y) in fast.iter().zip(&slow) {
            prop_assert!((x - y).abs() < 1e-12, "{} vs {}", x, y);
        }
        prop_assert!(balance_residual(&chain, &fast) < 1e-12);
    }

    #[test]
    fn riccati_residual_small(n in 1usize..=6, m in 1usize..=3, entries in prop::collection::vec(-1.0f64..1.0, 100), scale in 0.2f64..1.6) {
        if let Some(sys) = system(n, m, &entries, scale) {
            let floor = residual_floor(&sys);
            let residual = sys.residual();
            prop_assert!(residual <= 32.0 * floor, "residual {:e} > 32 x floor {:e}", residual, floor);
        }
    }

    #[test]
    fn cost_ordering(n in 1usize..=4, entries in prop::collection::vec(-1.0f64..1.0, 60), scale in 0.2f64..1.3,
                     lam in 0.05f64..0.95, z0 in 1u64..=5, t in 2u64..=30) {
        let Some(sys) = system(n, 1, &entries, scale) else { return Ok(()) };
        let a = 1.0 - lam;
        let w = sys.weighted_traces(a, ((z0 + 1) * (t + 1)) as usize + 2);
        let jon = j_online(&w, lam, OnlineDesign::fixed(z0).unwrap()).unwrap();
        let jmax = j_max(&sys, lam).unwrap();
        let mut prev = jon;
        for r in 0..t {
            let j = j_attack(&AttackChain::new(lam, z0, r, t).unwrap(), &w).unwrap();
            prop_assert!(j >= prev * (1.0 - 1e-12), "J not increasing in r: {} < {}", j, prev);
            prop_assert!(j <= jmax * (1.0 + 1e-12));
            prev = j;
        }
    }

    #[test]
    fn mixed_memory_masks_match_general_chain(lam in 0.05f64..0.95, z0 in 1u64..=4, mu in 0.0f64..=1.0,
                                               bits in prop::collection::vec(any::<bool>(), 1..9)) {
        prop_assume!(!bits.iter().all(|&b| b));
        let kmax = longest_cyclic_run(&bits) as u64;
        let tr = |i: usize| 1.0 + 0.3 * i as f64 + 1.1f64.powi(i as i32);
        let need = crate::renewal::periodic::tau_needed(z0, kmax) as usize;
        let w: Vec<f64> = (0..=need).map(|i| a_pow(lam, i) * tr(i)).collect();
        let design = OnlineDesign::new(z0, mu).unwrap();
        let seg = Segments::new(&w, lam, design, kmax).unwrap();
        let got = seg.j_mask(&bits).unwrap();
        let attack = Attack::mask(bits.clone()).unwrap();
        let (states, csr) = general::general_attack_chain(lam, design, &attack).unwrap();
        let pi = gth(&csr).unwrap();
        let expect: f64 = states.iter().zip(&pi).map(|(s, p)| p * tr(s.tau as usize)).sum();
        prop_assert!((got - expect).abs() < 1e-11 * expect, "{} vs {}", got, expect);
    }
}

fn a_pow(lam: f64, i: usize) -> f64 {
    (1.0 - lam).powi(i as i32)
}
