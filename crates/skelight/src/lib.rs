//! skelight: a physically based renderer that analyses the empty space of a scene to
//! sample light paths where ordinary estimators struggle.
//!
//! Data flow: scene files → [`scene`] (+ [`geometry`] BVH) → estimators in [`integrator`]
//! → [`film`] → [`eval`].

pub mod color;
pub mod geometry;
pub mod imageio;
pub mod material;
pub mod math;
pub mod sampling;
pub mod texture;
