//! The light-transport kit below the estimators: path vertices and their densities
//! ([`vertex`]), camera and light sub-paths ([`subpath`]), exact MIS over (s, t) strategies
//! ([`mis`], its bookkeeping explained once at its top; instant BPT's one-float form in
//! [`mis_chain`]), the connections each strategy makes ([`strategies`]), the path-tracing
//! walk with its direction-guide hook ([`walk`]), the bidirectional pixel sampler
//! ([`bidir`]), the one visibility seam every connection's shadow test goes through
//! ([`visibility`]) and the strategy factors of the power study ([`mutation`]).
//!
//! The kit knows nothing of any estimator or of the skeleton: estimators (and the guides
//! they bring) are built from it, never the other way round.

pub mod bidir;
pub mod mis;
pub mod mis_chain;
pub mod mutation;
pub mod strategies;
pub mod subpath;
pub mod vertex;
pub mod visibility;
pub mod walk;
