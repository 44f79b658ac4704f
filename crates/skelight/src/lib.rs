//! skelight: a physically based renderer that analyses the empty space of a scene to
//! sample light paths where ordinary estimators struggle.
//!
//! Data flow: scene files → [`scene`] (+ [`geometry`] BVH) → the empty-space analysis in
//! [`guided`] → the light-transport kit in [`paths`] → the estimators in [`estimators`]
//! (behind their registry; the contract and the render loop are [`integrator`]'s) →
//! [`film`] → [`eval`]. `docs/architecture.md` says which layer may use which. [`job`] is a render as the CLI, the Python package and Dask's
//! workers run it; [`shard`] splits a render's samples and merges them back; [`compare`]
//! runs equal-time studies.

// `!(x > 0.0)` is used on purpose throughout: unlike `x <= 0.0` it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod boundary;
pub mod camera;
pub mod checkpoint;
pub mod color;
pub mod compare;
pub mod debug;
pub mod estimators;
pub mod eval;
pub mod film;
pub mod geometry;
pub mod guided;
pub mod imageio;
pub mod integrator;
pub mod job;
pub mod light;
pub mod material;
pub mod math;
pub mod paths;
pub mod sampling;
pub mod scene;
pub mod shard;
pub mod texture;
