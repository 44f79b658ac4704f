//! Discrete shape analysis of the empty space of a scene (thesis ch. 5–6): voxelisation,
//! distance maps, opening maps and forests, opening-forest labels and portals, cubical
//! complexes and their homotopic thinning into the curvilinear skeleton (to come: piercing,
//! the skeleton graph, filtering and mapping). No renderer dependency: input is plain
//! triangles.

pub mod complex;
pub mod distance;
pub mod grid;
pub mod labeling;
pub mod opening;
pub mod pipeline;
pub mod portals;
pub mod skeleton;
#[cfg(test)]
mod testing;
pub mod thinning;
pub mod voxelize;

pub use grid::{Grid, GridError, GridSpec};
