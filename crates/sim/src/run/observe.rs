//! The seam where cross-cutting concerns attach to a run: the runner calls a [`RunObserver`] at
//! each event of a round — its start, the table set, every camera look, a recognition, the basket
//! chosen, a grasp planned and done, an attempt recorded, the round's end — as rapier's pipeline
//! calls its hooks. Recording ([`crate::run::record::RoundRecorder`]) is one; `()` observes
//! nothing. Observers only read: a run's results are the same with any observer.
//!
//! ```
//! use lgdm_sim::run::observe::RunObserver;
//! use lgdm_sim::run::results::AttemptRecord;
//! /// Counts the attempts as they end.
//! #[derive(Default)]
//! struct Count(usize);
//! impl RunObserver for Count {
//!     fn attempt_recorded(&mut self, _attempt: &AttemptRecord) {
//!         self.0 += 1;
//!     }
//! }
//! ```

use lgdm_pointcloud::grasp::GraspRectangle;

use crate::grasping::attempt::{Cell, Execution, GraspPlan};
use crate::perception::camera::SceneFrame;
use crate::physics::object::ObjectHandle;
use crate::physics::world::World;
use crate::recognition::recognizer::RecognitionRecord;
use crate::robot::gripper::GripperConfig;
use crate::run::results::{AttemptRecord, RoundRecord};
use crate::tasks::packing::BasketChoice;
use crate::tasks::scenario::{PlacedObject, Scenario};

/// An observer's error (recording's is a [`crate::run::record::RecordError`]); the run stops with
/// it.
pub type ObserverError = Box<dyn std::error::Error + Send + Sync>;

/// What a round is part of, for the observer.
#[derive(Debug, Clone, Copy)]
pub struct RoundInfo<'a> {
    /// Round number.
    pub round: usize,
    /// The scenario.
    pub scenario: Scenario,
    /// The grasp source's name.
    pub grasp_source: &'a str,
    /// The run's base seed.
    pub seed: u64,
    /// Where the objects came from.
    pub objects: &'a str,
}

/// Called by the runner at each event of a round. Every method does nothing by default.
pub trait RunObserver {
    /// A round starts in a fresh `world`, before its table is set.
    fn round_started(
        &mut self,
        _world: &mut World,
        _round: &RoundInfo<'_>,
    ) -> Result<(), ObserverError> {
        Ok(())
    }
    /// The table is set and the robot is at its ready pose.
    fn table_set(&mut self, _cell: &Cell, _objects: &[PlacedObject]) {}
    /// A camera took `shot`.
    fn camera_shot(&mut self, _world: &World, _camera: RecordCamera, _shot: &SceneFrame) {}
    /// The robot recognised `object` (its first look in the round).
    fn recognised(&mut self, _world: &World, _object: ObjectHandle, _record: &RecognitionRecord) {}
    /// Packing: the basket this attempt carries to.
    fn basket_chosen(&mut self, _world: &World, _choice: &BasketChoice) {}
    /// A grasp is planned and about to be tried.
    fn grasp_planned(&mut self, _world: &World, _grasp: &GraspShown<'_>) {}
    /// The grasp was tried (the arm is parked again); `basket` is where it carried to.
    fn grasp_done(
        &mut self,
        _cell: &Cell,
        _grasp: &GraspShown<'_>,
        _execution: &Execution,
        _basket: usize,
    ) -> Result<(), ObserverError> {
        Ok(())
    }
    /// An attempt's record is complete.
    fn attempt_recorded(&mut self, _attempt: &AttemptRecord) {}
    /// The round ended (the world is dropped after this).
    fn round_ended(
        &mut self,
        _world: &mut World,
        _round: &RoundRecord,
    ) -> Result<(), ObserverError> {
        Ok(())
    }
}

/// Observes nothing.
impl RunObserver for () {}

/// The cameras a recording shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RecordCamera {
    /// The fixed overview camera.
    Overview,
    /// The per-object close-up camera (moves from look to look).
    Closeup,
    /// A camera above the target basket (the outcome of a placement).
    Basket,
}

impl RecordCamera {
    /// Every camera, in channel order.
    pub(crate) const ALL: [RecordCamera; 3] = [Self::Overview, Self::Closeup, Self::Basket];

    /// `overview`, `closeup`, `basket`: topics `/camera/<name>/…`, frame `camera/<name>`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Overview => "overview",
            Self::Closeup => "closeup",
            Self::Basket => "basket",
        }
    }

    /// Its place in [`RecordCamera::ALL`].
    pub(crate) fn index(self) -> usize {
        self as usize
    }
}

/// What the recorder shows of a grasp.
#[derive(Debug, Clone)]
pub struct GraspShown<'a> {
    /// The plan.
    pub plan: &'a GraspPlan,
    /// Its rank among the source's grasps on the crop.
    pub rank: usize,
    /// The object aimed at (its name).
    pub object: Option<&'a str>,
    /// The gripper.
    pub gripper: &'a GripperConfig,
    /// The crop and the grasp rectangle in crop pixels.
    pub crop: Option<(&'a lgdm_pointcloud::crop::ObjectCrop, GraspRectangle)>,
}
