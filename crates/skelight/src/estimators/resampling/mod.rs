//! The resampling family (thesis ch. 11): estimators whose connections draw light vertices
//! from cached distributions instead of joining each pixel's own light sub-path. The shared
//! parts are public: the candidate pool and its tables ([`candidates`]), the tables cached
//! at skeleton nodes ([`node_tables`], `skelbpt`) and at importance records
//! ([`importance_cache`] over a [`kdtree`], `icbpt`), and the resampled join with its
//! parameters and report ([`join`]). The two estimators are leaves, reached through the
//! registry.

pub mod candidates;
mod icbpt;
pub mod importance_cache;
pub mod join;
pub mod kdtree;
pub mod node_tables;
mod skelbpt;

pub(super) use icbpt::IcBpt;
pub(super) use skelbpt::SkeletonBpt;
pub(super) use {icbpt::PARAMS as ICBPT_PARAMS, skelbpt::PARAMS as SKELBPT_PARAMS};
