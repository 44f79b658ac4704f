//! Where the renderer and the shape analysis meet: a scene's empty space analysed from its
//! triangles, camera and lights ([`analysis`]), kept in a form the hot loop reads without
//! locks ([`SkeletonGuide`]: the filtered skeleton graph and its node mapping grid), the
//! light-driven importance of its nodes ([`importance`]) and the directions towards them
//! ([`directions`]). The guided estimators (`skelpt`, and after it `skelbpt`, `portalpt`)
//! build on these.

pub mod analysis;
pub mod candidates;
pub mod directions;
pub mod importance;
pub mod importance_cache;
pub mod kdtree;
pub mod resampling;

pub use analysis::{guide_for, GuideSettings, SkeletonGuide};
