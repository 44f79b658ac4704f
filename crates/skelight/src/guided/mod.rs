//! Where the renderer and the shape analysis meet: a scene's empty space analysed from its
//! triangles, camera and lights ([`analysis`]), kept in a form the hot loop reads without
//! locks ([`SkeletonGuide`]: the filtered skeleton graph and its node mapping grid), the
//! light-driven importance of its nodes ([`importance`]) and the directions towards them
//! ([`directions`]), and the opening-forest regions with their portals ([`regions`]). The
//! guided estimators (`skelpt`, `skelbpt`, `portalpt`)
//! build on these; nothing here knows an estimator.

pub mod analysis;
pub mod directions;
pub mod guidance;
pub mod importance;
pub mod learning;
pub mod named_portals;
pub mod pictures;
pub mod regions;

pub use analysis::{guide_for, GuideSettings, SkeletonGuide};
pub use guidance::{Guidance, GuidanceSettings};
