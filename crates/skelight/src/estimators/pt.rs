//! `pt`: unidirectional path tracing with next-event estimation, multiple importance
//! sampling against BSDF sampling (power heuristic) and Russian roulette: the kit's walk
//! ([`crate::paths::walk::trace`]) with no guide.

use crate::color::Rgb;
use crate::geometry::Ray;
use crate::integrator::{Integrator, SampleContext};
use crate::math::vec2;
use crate::paths::walk::{trace, Unguided};
use crate::sampling::Rng;
use crate::scene::Scene;

#[derive(Clone, Debug, Default)]
pub struct PathTracer {
    /// Overrides the scene's `max_depth` when set.
    pub max_depth: Option<i32>,
}

impl PathTracer {
    /// Radiance arriving along `ray`.
    pub fn li(&self, scene: &Scene, ray: Ray, rng: &mut Rng) -> Rgb {
        trace(scene, self.max_depth.unwrap_or(scene.settings.max_depth), ray, rng, &Unguided, None)
    }
}

impl Integrator for PathTracer {
    fn name(&self) -> &'static str {
        "pt"
    }
    fn sample(&self, scene: &Scene, x: usize, y: usize, rng: &mut Rng, cx: &mut SampleContext) {
        let tile = &mut *cx.tile;
        let pos = vec2(x as f32, y as f32) + rng.next_2d();
        let ray = scene.camera.generate_ray(pos, rng.next_2d());
        let l = self.li(scene, ray, rng);
        tile.add(pos, l);
    }
}
