//! The Monte Carlo methods of [`LinearSystem`]: the protocol ([`crate::montecarlo`]) and the
//! closed-loop game ([`crate::montecarlo::game`]). The engines live in `montecarlo`; these are
//! their entries on the system, beside the exact quantities they are checked against.

use std::sync::atomic::{AtomicBool, AtomicU64};

use super::offline_takes_no_attack;
use crate::error::Result;
use crate::montecarlo::game::{self, GameConfig, GameRuns};
use crate::montecarlo::{self, McConfig, McResult, McSchedule};
use crate::system::LinearSystem;

impl LinearSystem {
    /// Monte Carlo of the real protocol (see [`crate::montecarlo`]); results depend on the seed
    /// only. Runs to the end: use [`LinearSystem::simulate_with`] to cancel or watch progress.
    pub fn simulate(&self, cfg: &McConfig) -> Result<McResult> {
        self.simulate_with(cfg, &AtomicBool::new(false), &AtomicU64::new(0))
    }

    /// [`LinearSystem::simulate`] that stops with [`Error::Interrupted`] soon after `cancel` is
    /// set and adds finished runs to `progress`.
    ///
    /// [`Error::Interrupted`]: crate::Error::Interrupted
    pub fn simulate_with(
        &self,
        cfg: &McConfig,
        cancel: &AtomicBool,
        progress: &AtomicU64,
    ) -> Result<McResult> {
        if matches!(cfg.schedule, McSchedule::Offline { .. }) && cfg.attack.is_some() {
            return Err(offline_takes_no_attack());
        }
        montecarlo::simulate(self, cfg, cancel, progress)
    }

    /// The closed-loop game Monte Carlo (see the [module docs](crate::montecarlo::game)).
    pub fn simulate_game(&self, cfg: &GameConfig) -> Result<GameRuns> {
        self.simulate_game_with(cfg, &AtomicBool::new(false), &AtomicU64::new(0))
    }

    /// [`LinearSystem::simulate_game`] that stops with [`Error::Interrupted`] soon after
    /// `cancel` is set and adds finished runs to `progress`.
    ///
    /// [`Error::Interrupted`]: crate::Error::Interrupted
    pub fn simulate_game_with(
        &self,
        cfg: &GameConfig,
        cancel: &AtomicBool,
        progress: &AtomicU64,
    ) -> Result<GameRuns> {
        game::simulate_on(self, cfg, cancel, progress, true)
    }
}
