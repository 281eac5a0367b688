//! Issue 43, item 3: an arm that would sweep through a basket wall re-plans the move or turns
//! it down. A third basket, a bin 15 cm across, stands on the table in the carry's path from
//! the drop region to the target basket: with walls 25 cm high the held can would sweep
//! through its wall (the check finds it before the move), and the carry is re-planned as a
//! lifted detour that clears it — the can is placed and nothing was touched; with walls 30 cm
//! high and a little nearer the arm no detour within reach clears it, and the carry is turned
//! down as `arm_collision` before it is made: the can is put back on the table.
//!
//! Run in release (`cargo test -p lgdm-sim --release --test arm_collisions`).

use lgdm_pointcloud::math::translation;
use lgdm_pointcloud::objects::procedural_object;
use lgdm_sim::grasping::attempt::{
    AttemptConfig, Cell, Execution, FailureReason, GraspPlan, execute, park, plan_grasp,
};
use lgdm_sim::grasping::source::{AnalyticSource, GraspQuery, GraspSource};
use lgdm_sim::perception::Perception;
use lgdm_sim::physics::config::{BasketConfig, WorldConfig};
use lgdm_sim::physics::world::{Scenery, World};
use lgdm_sim::robot::{ArmContactee, ArmPart, RobotConfig};
use lgdm_sim::tasks::scenario::on_table;
use lgdm_sim::timing::WallTimes;

/// A can at (0.08, −0.55) on the table, in a world with `bin` added as basket 2.
fn can_world(bin: Option<&BasketConfig>) -> World {
    let mut config = WorldConfig::default();
    config.baskets.extend(bin.cloned());
    let top = config.table.top_z_m();
    let mut world = World::new(config).unwrap();
    let can = procedural_object("can", 0, 2).unwrap();
    world
        .spawn_object("can", &can, &translation([0.08, -0.55, top]))
        .unwrap();
    world.settle();
    world
}

/// A bin standing on the table at (x, y), 15 cm across, its walls `height_m` high.
fn bin(x: f32, y: f32, height_m: f32) -> BasketConfig {
    let top = WorldConfig::default().table.top_z_m();
    BasketConfig {
        floor_center_m: [x, y, top + 0.01],
        inner_size_m: [0.15, 0.15],
        wall_height_m: height_m,
        ..BasketConfig::default()
    }
}

/// The analytic source's best grasp of the can, planned on the open table (the bin would hide
/// part of the can from the cameras; the plan is only numbers, the same in either world).
fn planned() -> GraspPlan {
    let config = AttemptConfig::default();
    let cell = Cell::at_ready(can_world(None), RobotConfig::default(), &config).unwrap();
    let perception = Perception::new(Default::default()).unwrap();
    let scene = perception.look(&cell.world).unwrap();
    let view = perception.close_up(&cell.world, &scene, 0).unwrap();
    let gripper = lgdm_sim::run::config::SimConfig::default().grasp_spec();
    let query = GraspQuery {
        crop: &view.crop,
        intrinsics: &view.shot.camera.intrinsics,
        gripper: &gripper,
        decode: &Default::default(),
    };
    let grasps = AnalyticSource::new().grasps(&query, 3).unwrap();
    let grasp = view.grasp_in_world(&grasps[0], &config.decode).unwrap();
    plan_grasp(&cell, &view, &grasp, &config)
}

/// Runs the plan in a world with `bin`, then parks (the way back must touch nothing); returns
/// what happened and whether the can is on the table then.
fn attempt(plan: &GraspPlan, bin: Option<&BasketConfig>) -> (Execution, bool) {
    let config = AttemptConfig::default();
    let mut cell = Cell::at_ready(can_world(bin), RobotConfig::default(), &config).unwrap();
    let can = cell.world.objects().next();
    let mut wall = WallTimes::default();
    let exec = execute(&mut cell, plan, can, &config, &mut wall).unwrap();
    park(&mut cell, plan.pregrasp_z_m, &config, &mut wall).unwrap();
    assert_eq!(cell.arm_contacts, [], "the way back touched something");
    let can = can.unwrap();
    cell.world.settle();
    (exec, on_table(&cell.world, can).unwrap())
}

fn touches_the_bin(exec: &Execution) -> bool {
    exec.measured
        .avoided_contacts
        .iter()
        .any(|c| c.with == ArmContactee::Scenery(Scenery::Basket(2)))
}

#[test]
fn a_carry_through_a_bin_wall_is_replanned_over_it() {
    let plan = planned();
    // Without the bin the carry goes straight: nothing to avoid.
    let (open, _) = attempt(&plan, None);
    assert!(open.placement_success, "{open:?}");
    assert_eq!(open.measured.detours, 0);
    assert_eq!(open.measured.avoided_contacts, []);
    // With it, the direct carry would sweep the held can through the bin's wall: re-planned.
    let (exec, _) = attempt(&plan, Some(&bin(0.45, -0.45, 0.25)));
    assert!(touches_the_bin(&exec), "{exec:?}");
    assert!(
        exec.measured
            .avoided_contacts
            .iter()
            .any(|c| matches!(c.part, ArmPart::Held | ArmPart::Gripper)),
        "{exec:?}"
    );
    assert_eq!(exec.measured.detours, 1, "{exec:?}");
    assert_eq!(exec.measured.arm_contacts, [], "{exec:?}");
    assert!(exec.grasp_success && exec.placement_success, "{exec:?}");
}

#[test]
fn a_carry_with_no_clear_detour_is_turned_down() {
    let plan = planned();
    let (exec, back_on_the_table) = attempt(&plan, Some(&bin(0.4, -0.4, 0.3)));
    assert!(exec.grasp_success, "{exec:?}");
    assert!(!exec.placement_success, "{exec:?}");
    assert_eq!(exec.reason, Some(FailureReason::ArmCollision), "{exec:?}");
    assert!(touches_the_bin(&exec), "{exec:?}");
    assert_eq!(exec.measured.detours, 0, "{exec:?}");
    assert_eq!(exec.measured.arm_contacts, [], "{exec:?}");
    // The can was put back where it was grasped, not dropped from the lift's height.
    assert!(back_on_the_table, "{exec:?}");
}
