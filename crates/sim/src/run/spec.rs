//! What a run is: [`RunSpec`] (scenario, rounds, seed, attempt budget, packing, categories
//! arriving over time) with every constant in [`SimConfig`], checked once by
//! [`RunSpec::validate`] before anything is played or written, with the run's errors
//! ([`SimError`]).
//!
//! ```
//! use lgdm_pointcloud::objects::{CATEGORIES, procedural_library};
//! use lgdm_sim::tasks::scenario::Scenario;
//! use lgdm_sim::run::error::SimError;
//! use lgdm_sim::run::spec::RunSpec;
//! let library = procedural_library(&CATEGORIES[..2], 1, 0).unwrap();
//! let mut spec = RunSpec::new(Scenario::Isolated, 3, 0);
//! spec.validate(&library, None).unwrap();
//! spec.rounds = 0;
//! assert!(matches!(spec.validate(&library, None), Err(SimError::Setting { name: "rounds", .. })));
//! ```

use lgdm_pointcloud::objects::ObjectModel;
use serde::{Deserialize, Serialize};

use crate::grasping::attempt::AttemptError;
use crate::recognition::labels::Labels;
use crate::robot::ik::{IkConfig, IkSolver, IkTarget, TopDownGrasp};
use crate::run::config::SimConfig;
use crate::run::error::SimError;
use crate::tasks::arrival::{Arrival, ArrivalError};
use crate::tasks::packing::{PackingError, PackingSpec};
use crate::tasks::scenario::{Scenario, check_library};

/// Checks every part of the config (here, with the run's errors, rather than in
/// [`crate::run::config`], which [`crate::run::results`] reads without them).
impl SimConfig {
    /// Checks every part.
    pub fn validate(&self) -> Result<(), SimError> {
        self.world.validate()?;
        self.shapes.validate()?;
        self.robot.validate().map_err(AttemptError::from)?;
        self.check_reach()?;
        self.cameras
            .validate()
            .map_err(|e| SimError::Perception(e.into()))?;
        self.attempt.validate()?;
        self.scenario.validate()?;
        Ok(())
    }
}

impl SimConfig {
    /// The arm, as mounted, must reach the table and the target basket pointing down: the
    /// drop region's centre 5 cm above the table top and the basket's centre 15 cm above its
    /// floor (the error names `robot.arm` and the point it cannot reach).
    fn check_reach(&self) -> Result<(), AttemptError> {
        let arm = self.robot.effective_arm();
        let mut ik = IkSolver::new(arm.clone(), IkConfig::default())?;
        let [x, y] = self.scenario.isolated_region.center_xy_m.map(f64::from);
        let mut targets = vec![(
            "the table",
            [x, y, f64::from(self.world.table.top_z_m()) + 0.05],
        )];
        if let Some(basket) = self.world.baskets.get(self.attempt.target_basket) {
            let [bx, by, bz] = basket.floor_center_m.map(f64::from);
            targets.push(("the target basket", [bx, by, bz + 0.15]));
        }
        for (what, p) in targets {
            let target = IkTarget::TopDown(TopDownGrasp::new(p, 0.0));
            if let Err(e) = ik.solve(&target, &arm.home_rad) {
                return Err(AttemptError::InvalidConfig {
                    field: "robot.arm",
                    reason: format!(
                        "the arm as mounted cannot reach {what} pointing down at ({:.3}, {:.3}, \
                         {:.3}) m: {e}",
                        p[0], p[1], p[2]
                    ),
                });
            }
        }
        Ok(())
    }
}

/// The most rounds a run may ask for (100,000 isolated rounds are ~10 h of this machine).
pub const MAX_ROUNDS: usize = 100_000;

/// The largest attempt budget a run may ask for (each attempt's record is ~2 KB in
/// `results.json`).
pub const MAX_ATTEMPTS: usize = 100_000;

/// What to run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunSpec {
    /// The scenario.
    pub scenario: Scenario,
    /// Rounds to play (1 to [`MAX_ROUNDS`]).
    pub rounds: usize,
    /// Base seed.
    pub seed: u64,
    /// Where the objects came from (`procedural` or the meshes directory), for the record.
    pub objects: String,
    /// Stop after this many attempts in all (1 to [`MAX_ATTEMPTS`]; none: play every round).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_attempts: Option<usize>,
    /// Packing: each object goes to the basket of the category it is recognised as (none: every
    /// object to [`crate::grasping::attempt::AttemptConfig::target_basket`]). Needs recognition
    /// ([`crate::run::runner::run_pick_place`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub packing: Option<PackingSpec>,
    /// Categories arriving over time, and the end-of-run evaluation of the early ones (none: every
    /// round draws from the whole library). Needs recognition
    /// ([`crate::run::runner::run_pick_place`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub arrival: Option<Arrival>,
    /// Every constant.
    pub config: SimConfig,
}

impl RunSpec {
    /// A run of the procedural objects with the default config.
    pub fn new(scenario: Scenario, rounds: usize, seed: u64) -> Self {
        Self {
            scenario,
            rounds,
            seed,
            objects: "procedural".into(),
            max_attempts: None,
            packing: None,
            arrival: None,
            config: SimConfig::default(),
        }
    }

    /// Checks the run before anything is played or written: rounds and attempt budget, the
    /// config, every object of `library` (its hull, its size on the table), and — with
    /// recognition, whose model knows `labels` — the packing targets and the arrival plan.
    /// Packing and arrival need recognition (`labels` is `None` without it).
    pub fn validate(
        &self,
        library: &[ObjectModel],
        labels: Option<&Labels>,
    ) -> Result<(), SimError> {
        if self.rounds == 0 {
            return Err(SimError::Setting {
                name: "rounds",
                value: "0".into(),
                reason: "at least one round is needed".into(),
            });
        }
        if self.rounds > MAX_ROUNDS {
            return Err(SimError::Setting {
                name: "rounds",
                value: self.rounds.to_string(),
                reason: format!("at most {MAX_ROUNDS} rounds a run"),
            });
        }
        if self.max_attempts.is_some_and(|a| a > MAX_ATTEMPTS) {
            return Err(SimError::Setting {
                name: "attempts",
                value: self.max_attempts.unwrap_or_default().to_string(),
                reason: format!("at most {MAX_ATTEMPTS} attempts a run"),
            });
        }
        if self.max_attempts == Some(0) {
            return Err(SimError::Setting {
                name: "attempts",
                value: "0".into(),
                reason: "at least one attempt is needed".into(),
            });
        }
        if library.is_empty() {
            return Err(SimError::EmptyLibrary);
        }
        self.config.validate()?;
        // The baskets objects go into; any other is scenery (a bin in the way, say).
        let targets = match &self.packing {
            Some(p) => vec![p.target_basket, p.other_basket],
            None => vec![self.config.attempt.target_basket],
        };
        check_library(&self.config.world, library, &targets)?;
        if let Some(packing) = &self.packing {
            let Some(labels) = labels else {
                return Err(PackingError::NoRecognition.into());
            };
            let known = crate::tasks::packing::known_categories(library, labels);
            packing.validate(&known, &self.config.world)?;
        }
        if let Some(arrival) = &self.arrival {
            if labels.is_none() {
                return Err(ArrivalError::NoRecognition.into());
            }
            arrival.validate(self.rounds)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Translation3, UnitQuaternion};

    /// An arm stood 2 m from the table cannot reach it: refused before any work, naming the
    /// field; the default mounting passes.
    #[test]
    fn an_arm_that_cannot_reach_the_table_is_refused() {
        SimConfig::default().validate().unwrap();
        let mut config = SimConfig::default();
        let far = Isometry3::from_parts(
            Translation3::new(0.0, 2.0, 0.785),
            UnitQuaternion::identity(),
        );
        config.robot.arm = config.robot.arm.clone().with_world_from_base(&far);
        let err = config.validate().unwrap_err().to_string();
        assert!(err.contains("robot.arm"), "{err}");
        assert!(err.contains("cannot reach the table"), "{err}");
    }
}
