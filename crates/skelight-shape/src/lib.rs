//! Discrete shape analysis of the empty space of a scene (thesis ch. 5–6): voxelisation,
//! distance maps, opening maps and forests, and — to come — cubical-complex thinning and the
//! curvilinear skeleton. No renderer dependency: input is plain triangles.

pub mod distance;
pub mod grid;
pub mod labeling;
pub mod opening;
pub mod portals;
pub mod voxelize;

pub use grid::{Grid, GridError, GridSpec};
