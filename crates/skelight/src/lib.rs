//! skelight: a physically based renderer that analyses the empty space of a scene to
//! sample light paths where ordinary estimators struggle.
//!
//! Data flow: scene files → [`scene`] (+ [`geometry`] BVH) → estimators in [`integrator`]
//! → [`film`] → [`eval`].

// `!(x > 0.0)` is used on purpose throughout: unlike `x <= 0.0` it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod boundary;
pub mod camera;
pub mod checkpoint;
pub mod color;
pub mod eval;
pub mod film;
pub mod geometry;
pub mod guided;
pub mod imageio;
pub mod integrator;
pub mod light;
pub mod material;
pub mod math;
pub mod sampling;
pub mod scene;
pub mod texture;
