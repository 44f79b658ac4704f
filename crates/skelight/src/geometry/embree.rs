//! Embree 3 behind the [`Accelerator`] trait (cargo feature `embree`, Debian's
//! `libembree-dev`), so the built-in BVH can be measured against it on the same rays.
//! Triangles keep the global order of the scene, so Embree's primitive id is ours.

use embree3::{BufferUsage, Device, Format, GeometryKind, IntersectContext, Ray as ERay, RayHit, Scene};

use super::{Accelerator, BuildTriangle, Hit, HitFilter, Ray};
use crate::math::{vec3, Aabb};

pub struct EmbreeAccel {
    // Field order matters: the scene must be dropped before the device.
    scene: Scene<'static>,
    _device: Device,
    masked: Vec<bool>,
    any_masked: bool,
    bounds: Aabb,
}

#[derive(Debug, thiserror::Error)]
#[error("Embree: {0}")]
pub struct EmbreeError(String);

impl EmbreeAccel {
    pub fn build(triangles: &[BuildTriangle]) -> Result<EmbreeAccel, EmbreeError> {
        let err = |e: embree3::Error| EmbreeError(format!("{e:?}"));
        let device = Device::new().map_err(err)?;
        let mut scene = device.create_scene().map_err(err)?;
        let mut bounds = Aabb::EMPTY;
        if !triangles.is_empty() {
            let n = triangles.len();
            let mut geom = device.create_geometry(GeometryKind::TRIANGLE).map_err(err)?;
            let mut verts =
                geom.set_new_buffer::<[f32; 3]>(BufferUsage::VERTEX, 0, Format::FLOAT3, 12, 3 * n).map_err(err)?;
            for (i, t) in triangles.iter().enumerate() {
                for k in 0..3 {
                    verts[3 * i + k] = [t.v[k].x, t.v[k].y, t.v[k].z];
                    bounds.grow(t.v[k]);
                }
            }
            let mut idx = geom.set_new_buffer::<[u32; 3]>(BufferUsage::INDEX, 0, Format::UINT3, 12, n).map_err(err)?;
            for (i, t) in idx.iter_mut().enumerate() {
                let b = 3 * i as u32;
                *t = [b, b + 1, b + 2];
            }
            let geom = geom.commit();
            scene.attach_geometry(&geom);
        }
        scene.commit();
        let masked: Vec<bool> = triangles.iter().map(|t| t.masked).collect();
        let any_masked = masked.iter().any(|&m| m);
        Ok(EmbreeAccel { scene, _device: device, masked, any_masked, bounds })
    }

    fn closest(&self, ray: &Ray, tnear: f32) -> Option<Hit> {
        let r = ERay::segment([ray.o.x, ray.o.y, ray.o.z], [ray.d.x, ray.d.y, ray.d.z], tnear, ray.tmax);
        let mut rh = RayHit::from(r);
        let mut ctx = IntersectContext::incoherent();
        self.scene.intersect(&mut ctx, &mut rh);
        rh.hit.is_valid().then_some(Hit { t: rh.ray.tfar, prim: rh.hit.primID, b1: rh.hit.u, b2: rh.hit.v })
    }
}

impl Accelerator for EmbreeAccel {
    fn intersect(&self, ray: &Ray, filter: &dyn HitFilter) -> Option<Hit> {
        let mut tnear = 0.0;
        loop {
            let hit = self.closest(ray, tnear)?;
            if !self.masked[hit.prim as usize] || filter.accept(ray, hit.prim, hit.b1, hit.b2) {
                return Some(hit);
            }
            // Rejected by the alpha mask: continue just beyond it.
            tnear = hit.t * (1.0 + 1e-6) + 1e-7;
        }
    }
    fn occluded(&self, ray: &Ray, filter: &dyn HitFilter) -> bool {
        if self.any_masked {
            return self.intersect(ray, filter).is_some();
        }
        let mut r = ERay::segment([ray.o.x, ray.o.y, ray.o.z], [ray.d.x, ray.d.y, ray.d.z], 0.0, ray.tmax);
        let mut ctx = IntersectContext::incoherent();
        self.scene.occluded(&mut ctx, &mut r)
    }
    fn bounds(&self) -> Aabb {
        if self.bounds.is_empty() {
            Aabb { min: vec3(0.0, 0.0, 0.0), max: vec3(0.0, 0.0, 0.0) }
        } else {
            self.bounds
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Bvh, NoFilter};
    use crate::math::Vec3;
    use crate::sampling::{uniform_sphere, Rng};

    /// Embree and the built-in BVH find the same hits.
    #[test]
    fn agrees_with_the_builtin_bvh() {
        let mut rng = Rng::new(9, 0, 0);
        let tris: Vec<BuildTriangle> = (0..3000)
            .map(|_| {
                let c = vec3(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 10.0;
                let v = [0, 1, 2].map(|_| c + vec3(rng.next_f32() - 0.5, rng.next_f32() - 0.5, rng.next_f32() - 0.5));
                BuildTriangle { v, masked: false }
            })
            .collect();
        let (bvh, emb) = (Bvh::build(&tris), EmbreeAccel::build(&tris).unwrap());
        for _ in 0..2000 {
            let o = vec3(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 12.0 - Vec3::splat(1.0);
            let ray = Ray::new(o, uniform_sphere(rng.next_2d()));
            let (a, b) = (bvh.intersect(&ray, &NoFilter), emb.intersect(&ray, &NoFilter));
            match (a, b) {
                (None, None) => {}
                (Some(a), Some(b)) => assert!((a.t - b.t).abs() <= 1e-4 * a.t.max(1.0), "{a:?} {b:?}"),
                other => panic!("{other:?}"),
            }
            assert_eq!(bvh.occluded(&ray, &NoFilter), emb.occluded(&ray, &NoFilter));
        }
    }
}
