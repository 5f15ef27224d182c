//! The paper's example through the crate's API alone: A = 1.2, C = 0.7, Q = R = 0.8, λ = 0.5,
//! energy ratio 1/7 (Ψ = 9/7, Δ = 3, δ = 1), in the corrected model.
//!
//! `cargo run --release --example paper` prints one line per quantity, name then value.

use fakeack::Scenario;
use fakeack::{design_online, Attack, Attacker, Channel, LinearSystem, PowerSchedule, Ratio};

fn main() -> Result<(), fakeack::Error> {
    let system = LinearSystem::scalar(1.2, 0.7, 0.8, 0.8)?;
    let (lam, ratio) = (0.5, Ratio::new(1, 7)?);
    let design = design_online(lam, ratio)?;
    let j_attack = |r, t| system.j_attack(lam, design, &Attack::periodic(r, t)?);
    let bar = system.beta_bar(lam, ratio, design, 60)?;
    let finite = match bar.finite {
        Some((r, t)) => format!("{r}/{t}"),
        None => "none".to_string(),
    };
    println!("pbar {}", system.pbar()[(0, 0)]);
    println!("j_offline {}", system.j_offline(lam, ratio)?);
    println!("j_online {}", system.j_online(lam, design)?);
    println!("j_attack_1_5 {}", j_attack(1, 5)?);
    println!("j_attack_2_3 {}", j_attack(2, 3)?);
    println!("j_max {}", system.j_max(lam)?);
    println!("beta_bar_limit {}", bar.limit);
    println!("beta_bar_t60 {finite}");
    let engine = Scenario::new(
        system.clone(),
        Channel::bernoulli(lam)?,
        PowerSchedule::Online(design),
        Attacker::attack(Attack::periodic(1, 5)?),
    )?;
    println!("engine_j_attack_1_5 {}", engine.cost()?);
    Ok(())
}
