//! The likelihood-ratio window test: alarm counts derived by hand on a deterministic protocol
//! (the opening at each window's gap, its continuation past the table, the dormant statistic
//! after a fall-back), and a test that never alarms plays the online schedule bit for bit.

use super::super::*;
use super::{config, paper};

const INF: f64 = f64::INFINITY;

fn lr(
    inc_flag: &[f64],
    inc_quiet: &[f64],
    opening: &[f64],
    critical: f64,
    fallback: u64,
) -> Policy {
    Policy::Test {
        detector: Detector::Likelihood {
            inc_flag: inc_flag.to_vec(),
            inc_quiet: inc_quiet.to_vec(),
            opening: opening.to_vec(),
            critical,
        },
        harmful_at_most: None,
        fallback,
        min_gap: 0,
    }
}

/// The CUSUM's protocol without chance (one channel state where high power always arrives and
/// low power never does, z0 = 2, μ = 1, no attack: online a flag-ACK reaches the sensor every
/// third step, 3, 6, 9, ...), falling back to high power, where no flag is sent.
fn deterministic(policy: Policy, window: u64, horizon: u64) -> GameConfig {
    super::cusum::deterministic(policy, vec![1], window, horizon)
}

/// Every run's (alarms, tested windows) equals `want`.
fn check(what: &str, cfg: &GameConfig, want: [u64; 2]) {
    let res = simulate_on(
        &paper(),
        cfg,
        &AtomicBool::new(false),
        &AtomicU64::new(0),
        true,
    )
    .unwrap();
    for r in 0..cfg.runs as usize {
        assert_eq!([res.alarms[r], res.tested[r]], want, "{what}, run {r}");
    }
}

#[test]
fn alarm_counts_derived_by_hand() {
    // Windows of 6 steps each start one step after a flag-ACK (y = 1) and hold two gaps of 3:
    // Λ = o1 + 2 (q1 + q2 + a3) = 0.5 + 2 * 0.75 = 2 exactly (dyadic values), an alarm at
    // critical 2 (Λ >= critical) and none just above.
    let (flag, quiet, open) = ([0.0, 0.0, 0.375], [0.125, 0.25, 0.0], [0.5, 0.0, 0.0]);
    let at = |c: f64| deterministic(lr(&flag, &quiet, &open, c, 0), 6, 36);
    check("at the critical value", &at(2.0), [6, 6]);
    check("just above it", &at(2.0 + 1e-9), [0, 6]);

    // Windows of 4 steps start at gaps 1, 2, 3 in turn (flag-ACKs at 3, 6, 9, 12; windows at 1,
    // 5, 9): Λ = o1 + 2 q1 + q2 + a3, o2 + q1 + 2 q2 + a3, o3 + q1 + q2 + 2 a3. With only o3 = 1
    // and a3 = 0.5: 0.5, 0.5, 2; the third alarms at critical 1.5, in 2 of 6 windows.
    let policy = lr(&[0.0, 0.0, 0.5], &[0.0; 3], &[0.0, 0.0, 1.0], 1.5, 0);
    check("the opening's gap", &deterministic(policy, 4, 24), [2, 6]);

    // Tables of one entry: past it the opening grows by the last quiet increment per step, so
    // the windows at gaps 1, 2, 3 open at 0, 1, 2 and add their silent steps (3, 3, 2): Λ = 3,
    // 4, 4; at critical 3.5 the second and third alarm, 4 of 6 windows.
    let policy = lr(&[0.0], &[1.0], &[0.0], 3.5, 0);
    check(
        "the opening past the table",
        &deterministic(policy, 4, 24),
        [4, 6],
    );

    // Every flag-ACK alarms (+inf), with 1 window offline: 1-4 alarms (flag-ACK at 3); 5-8
    // offline at high power, no flag; online at 9 (low power), a flag-ACK at 10, which the
    // dormant statistic only takes as its start: 9-12 has Λ = 0; the flag-ACK at 13 alarms in
    // 13-16; 17-20 offline; 21-24 quiet; 25-28 alarms. 5 windows tested, 3 alarms. Without
    // the dormancy the flag-ACK at 10 (gap 7) would alarm too.
    let policy = lr(&[INF], &[0.0], &[0.0], 1.0, 1);
    check(
        "dormant after a fall-back",
        &deterministic(policy, 4, 28),
        [3, 5],
    );
    // A -inf before the +inf: still an alarm, never NaN.
    let policy = lr(&[INF], &[-INF], &[0.0], 1.0, 1);
    check("+inf after -inf", &deterministic(policy, 4, 28), [3, 5]);
}

#[test]
fn a_test_that_never_alarms_is_the_online_schedule() {
    // The statistic draws nothing: with an unreachable critical value the policy plays the
    // online schedule draw for draw, on the lane kernel.
    let sys = paper();
    let never = lr(&[0.5; 3], &[-0.25; 3], &[0.0; 3], 1e300, 2);
    let injection = Attack::injection(0.03, Some(Attack::random(0.2).unwrap())).unwrap();
    for attack in [None, Some(Attack::random(0.3).unwrap()), Some(injection)] {
        let mut online = config(attack, Policy::Online);
        online.runs = 20;
        online.horizon = 3000;
        online.burn_in = 500;
        let with = GameConfig {
            policy: never.clone(),
            ..online.clone()
        };
        let run = |cfg: &GameConfig, sliced| {
            simulate_on(
                &sys,
                cfg,
                &AtomicBool::new(false),
                &AtomicU64::new(0),
                sliced,
            )
            .unwrap()
        };
        let (a, b) = (run(&online, false), run(&with, true));
        let what = format!("{:?}", online.attack);
        assert_eq!(a.cost, b.cost, "{what}");
        assert_eq!(a.high_power, b.high_power, "{what}");
        assert_eq!(a.delivered, b.delivered, "{what}");
        assert!(b.alarms.iter().all(|&n| n == 0), "{what}");
        assert!(
            b.tested.iter().all(|&n| n == 3),
            "{what}: 3 measured windows"
        );
    }
}

#[test]
fn malformed_tables_are_refused() {
    let bad = [
        (lr(&[], &[], &[], 1.0, 0), "inc_flag"),
        (lr(&[0.0], &[0.0, 0.0], &[0.0], 1.0, 0), "inc_quiet"),
        (lr(&[0.0], &[0.0], &[0.0, 1.0], 1.0, 0), "opening"),
        (lr(&[f64::NAN], &[0.0], &[0.0], 1.0, 0), "inc_flag"),
        (lr(&[0.0], &[0.0], &[f64::NAN], 1.0, 0), "opening"),
        (lr(&[0.0], &[0.0], &[0.0], INF, 0), "critical"),
    ];
    for (policy, arg) in bad {
        let err = config(None, policy).validate().unwrap_err();
        assert!(
            matches!(&err, Error::InvalidArgument { arg: a, .. } if a == arg),
            "{arg}: {err:?}"
        );
    }
}
