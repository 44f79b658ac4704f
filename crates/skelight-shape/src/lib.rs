//! Discrete shape analysis of the empty space of a scene (thesis ch. 5–6): voxelisation,
//! distance maps, opening maps and forests, opening-forest labels and portals, cubical
//! complexes and their homotopic thinning into the curvilinear skeleton, the skeleton graph,
//! its filtering and the mapping of voxels and surface points to its nodes. No renderer
//! dependency: input is plain triangles.

pub mod bottlenecks;
pub mod complex;
pub mod distance;
pub mod filter;
pub mod grid;
pub mod labeling;
pub mod mapping;
pub mod opening;
pub mod pipeline;
pub mod portals;
pub mod reach;
mod simd;
pub mod skeleton;
#[cfg(test)]
mod testing;
pub mod thinning;
pub mod voxelize;

pub use grid::{Grid, GridError, GridSpec};
