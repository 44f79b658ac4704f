//! What a skeleton-guided path tracer reads (thesis ch. 9, seed 001): the scene's analysis
//! ([`super::analysis`]), the importance of every skeleton node estimated from light rays
//! (eq. 171–176, [`super::importance`]) and, for every node, the importance points towards
//! the importance nodes along the shortest skeleton paths with their selection
//! probabilities (eq. 162–165, [`super::directions`]). `skelpt` prepares it once per render;
//! tests and pictures prepare the same thing from the same parameters.

use std::sync::Arc;

use super::analysis::prepare_guide;
use super::directions::Directions;
use super::importance::{importance_nodes, incident_power};
use super::{GuideSettings, SkeletonGuide};
use crate::integrator::params::Params;
use crate::integrator::{Preparation, PrepareError};
use crate::scene::Scene;

/// Seed of the importance estimate's random stream (fixed: the preparation is part of the
/// estimator, the same for every render seed).
const IMPORTANCE_SEED: u64 = 0x5ce1_e70f;

/// How the guidance is prepared (skelpt's parameters of the same names).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GuidanceSettings {
    pub guide: GuideSettings,
    pub importance_rays: usize,
    pub importance_bounces: u32,
    pub importance_nodes: usize,
}

impl GuidanceSettings {
    /// From parameters that declare `resolution`, `bounds`, `importance_rays`, `importance_bounces`
    /// and `importance_nodes` (skelpt's).
    pub fn from_params(p: &Params) -> GuidanceSettings {
        GuidanceSettings {
            guide: GuideSettings::from_params(p),
            importance_rays: p.int("importance_rays") as usize,
            importance_bounces: p.int("importance_bounces") as u32,
            importance_nodes: p.int("importance_nodes") as usize,
        }
    }
}

/// The prepared guidance.
pub struct Guidance {
    pub guide: Arc<SkeletonGuide>,
    pub directions: Directions,
    /// The importance nodes and their values, brightest first.
    pub importance: Vec<(u32, f64)>,
}

impl Guidance {
    /// Prepares the guidance for `scene` (which has lights), its stages and notes added to
    /// `prep`; `None`, with a note, where no light ray reached a skeleton node.
    pub fn prepare(
        scene: &Scene,
        settings: &GuidanceSettings,
        prep: &mut Preparation,
    ) -> Result<Option<Guidance>, PrepareError> {
        let guide = prepare_guide(scene, &settings.guide, prep)?;
        let lap = std::time::Instant::now();
        let values =
            incident_power(scene, &guide, settings.importance_rays, settings.importance_bounces, IMPORTANCE_SEED);
        let importance = importance_nodes(&values, settings.importance_nodes);
        prep.stages.push(("importance from light rays (eq. 176)".into(), lap.elapsed().as_secs_f64()));
        let lap = std::time::Instant::now();
        let directions = Directions::build(scene, &guide, &importance);
        prep.stages.push(("shortest paths and importance points (eq. 162–165)".into(), lap.elapsed().as_secs_f64()));
        let lit = values.iter().filter(|v| **v > 0.0).count();
        prep.notes.push(format!(
            "skeleton: {} nodes, {} edges; {lit} lit, {} importance nodes; {} targets; {:.1} MB kept for sampling",
            guide.graph.nodes.len(),
            guide.graph.edges.len(),
            importance.len(),
            directions.len(),
            (guide.bytes + directions.bytes()) as f64 / 1e6
        ));
        if importance.is_empty() {
            prep.notes.push("no light ray reached a skeleton node: plain path tracing".into());
            return Ok(None);
        }
        Ok(Some(Guidance { guide, directions, importance }))
    }
}
