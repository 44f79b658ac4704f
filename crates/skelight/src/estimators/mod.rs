//! The estimators, each a leaf: one file (or, for the resampling family, one folder) per
//! estimator, built from the kit ([`crate::paths`]), the analysis ([`crate::guided`]) and
//! the contract ([`crate::integrator`]). Nothing imports an estimator module but the
//! [`registry`] (the modules are private): the CLI, Python, the GPU crate and the tests
//! reach estimators by name, their parameters by the registry's specs, their pictures by
//! [`crate::integrator::Integrator::diagnostics`].

mod bpt;
mod ibpt;
mod lt;
mod portalpt;
mod pt;
pub mod registry;
pub mod resampling;
mod skelpt;

pub use registry::{by_name, create, create_for_scene, find, names, parse_spec, Estimator, ESTIMATORS};
