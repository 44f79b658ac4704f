//! How often a join of an eye vertex with a light vertex is unoccluded, for bpt's own light
//! sub-path and for the candidates skelbpt and icbpt resample (issue 33: "visibility rate of
//! connections before/after resampling"). Only joins whose unoccluded contribution is not
//! zero are counted (a join the BSDFs or cosines already kill needs no shadow ray).
//!
//! ```sh
//! cargo run --release --example join_visibility -- scenes/door-corner.toml 128 64
//! ```

use skelight::estimators::resampling::candidates::Combination;
use skelight::estimators::resampling::importance_cache::{CacheInput, ImportanceCache, Nearby};
use skelight::estimators::resampling::node_tables::NodeSelection;
use skelight::estimators::resampling::node_tables::{BuildInput, Resampling};
use skelight::guided::GuideSettings;
use skelight::integrator::params::Params;
use skelight::integrator::Preparation;
use skelight::math::vec2;
use skelight::paths::mis::Heuristic;
use skelight::paths::strategies::edge;
use skelight::paths::subpath::{camera_subpath, LightPaths};
use skelight::paths::vertex::{Vertex, VertexKind};
use skelight::paths::visibility::visible;
use skelight::sampling::Rng;

/// Joins counted (unoccluded contribution not zero) and those visible.
#[derive(Default)]
struct Rate(u64, u64);

impl Rate {
    fn add(&mut self, scene: &skelight::scene::Scene, light: &[Vertex], s: usize, camera: &[Vertex], t: usize) {
        let (y, z) = (&light[s - 1], &camera[t - 1]);
        let Some(e) = edge(scene, y, &light[s - 2], z, &camera[t - 2]) else { return };
        if (y.beta * e.light_end.f * e.camera_end.f).is_black() {
            return;
        }
        self.0 += 1;
        self.1 += visible(scene, z, y) as u64;
    }
    fn line(&self, name: &str) -> String {
        format!("{name:>8}: {:>8} joins, {:5.1} % unoccluded", self.0, 100.0 * self.1 as f64 / self.0.max(1) as f64)
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let (path, w, h) = match &args[..] {
        [_, p, w, h] => (p.clone(), w.parse().expect("width"), h.parse().expect("height")),
        _ => {
            eprintln!("usage: join_visibility SCENE WIDTH HEIGHT");
            std::process::exit(2);
        }
    };
    let mut scene = skelight::scene::load::load(std::path::Path::new(&path), &[]).unwrap_or_else(|e| {
        eprintln!("{e}");
        std::process::exit(1)
    });
    scene.set_resolution(w, h);
    let max_depth = scene.settings.max_depth;
    let deepest = skelight::estimators::resampling::join::deepest_join(max_depth);
    let p = Params::new("skelbpt", skelight::estimators::find("skelbpt").unwrap().params, &[]).unwrap();
    let settings = GuideSettings::from_params(&p);
    let skel = NodeSelection::prepare(&scene, &settings, p.float("acceptance"), max_depth, &mut Preparation::default())
        .expect("skelbpt prepares");
    let mut paths = LightPaths::default();
    paths.trace(&scene, w * h, 1, 0, max_depth);
    let mut table = Resampling::default();
    let (guide, accepted) = (&*skel.guide, &skel.accepted[..]);
    let input = BuildInput {
        guide,
        accepted,
        candidates: 1024,
        combination: Combination::Max,
        heuristic: Heuristic::Balance,
        deepest,
        seed: 1,
        iteration: 0,
    };
    table.build(&scene, &paths, &input);
    let mut cache = ImportanceCache::default();
    let cache_input = CacheInput {
        record_paths: ((w * h) as f64 * 0.001).ceil() as usize,
        candidates: 1024,
        combination: Combination::Max,
        heuristic: Heuristic::Balance,
        deepest,
        max_depth,
        seed: 1,
        iteration: 0,
    };
    cache.build(&scene, &paths, &cache_input);
    let (mut own, mut uniform, mut skel_rate, mut ic_rate) =
        (Rate::default(), Rate::default(), Rate::default(), Rate::default());
    let mut rng = Rng::new(3, 0, 0);
    let (mut camera, mut nearby) = (Vec::new(), Nearby::default());
    for _ in 0..20_000 {
        let pixel = (rng.next_f32() * (w * h) as f32) as usize % (w * h);
        let raster = vec2((pixel % w) as f32 + rng.next_f32(), (pixel / w) as f32 + rng.next_f32());
        camera_subpath(&scene, raster, &mut rng, max_depth, &mut camera);
        let light = paths.path(pixel);
        for t in 2..=camera.len() {
            let z = &camera[t - 1];
            if z.kind != VertexKind::Surface || !z.can_connect(&scene) {
                continue;
            }
            let node = guide.node_at(z.p(), z.n(), z.si.wi);
            cache.nearby(z, &mut nearby);
            for s in 2..=table.depths() + 1 {
                if max_depth >= 0 && s + t > max_depth as usize + 1 {
                    break;
                }
                if light.len() >= s {
                    own.add(&scene, light, s, &camera, t);
                }
                if let Some(d) = table.draw(node, s, rng.next_u32()) {
                    let rate = if d.origin == skelight::estimators::resampling::node_tables::Origin::Fallback {
                        &mut uniform
                    } else {
                        &mut skel_rate
                    };
                    rate.add(&scene, table.path(d.candidate), s, &camera, t);
                }
                if let Some(d) = cache.draw(nearby.records(), s, (rng.next_u32(), rng.next_u32()), Combination::Max) {
                    ic_rate.add(&scene, cache.path(d.candidate), s, &camera, t);
                }
            }
        }
    }
    println!("{path} at {w}×{h}, joins s, t ≥ 2 from 20 000 eye sub-paths:");
    println!("{}", own.line("bpt"));
    println!("{}", skel_rate.line("skelbpt"));
    println!("{}", uniform.line("fallback"));
    println!("{}", ic_rate.line("icbpt"));
}
