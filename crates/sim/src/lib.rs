//! Tabletop simulation: a kinematic arm and a parallel-jaw gripper that recognise, grasp and place
//! objects. Not built yet: this crate only reserves its place in the workspace.
