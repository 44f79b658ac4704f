//! Rays, hits and the acceleration structures that find them.

mod bvh;
#[cfg(feature = "embree")]
mod embree;
mod sphere;
mod triangle;

pub use bvh::{Bvh, BvhStats};
#[cfg(feature = "embree")]
pub use embree::{EmbreeAccel, EmbreeError};
pub use sphere::Sphere;
pub use triangle::{intersect_triangle, RayPrecomp};

use crate::math::{Aabb, Vec3};

/// A ray `o + t·d`, `t` in `(0, tmax)`. `d` need not be unit length.
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    pub o: Vec3,
    pub d: Vec3,
    pub tmax: f32,
}

impl Ray {
    pub fn new(o: Vec3, d: Vec3) -> Ray {
        Ray { o, d, tmax: f32::INFINITY }
    }
    #[inline]
    pub fn at(&self, t: f32) -> Vec3 {
        self.o + self.d * t
    }
}

/// The closest intersection: global triangle index and barycentrics of vertices 1 and 2.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    pub prim: u32,
    pub b1: f32,
    pub b2: f32,
}

/// A triangle as the accelerator sees it: three world-space vertices and whether an
/// alpha mask must be consulted before accepting a hit on it.
#[derive(Clone, Copy, Debug)]
pub struct BuildTriangle {
    pub v: [Vec3; 3],
    pub masked: bool,
}

impl BuildTriangle {
    pub fn bounds(&self) -> Aabb {
        let mut b = Aabb::EMPTY;
        self.v.iter().for_each(|&p| b.grow(p));
        b
    }
}

/// Decides whether a candidate hit on a masked triangle counts (alpha test).
pub trait HitFilter: Sync {
    fn accept(&self, ray: &Ray, prim: u32, b1: f32, b2: f32) -> bool;
}

/// Accepts every hit: for scenes or callers without masks.
pub struct NoFilter;
impl HitFilter for NoFilter {
    #[inline]
    fn accept(&self, _: &Ray, _: u32, _: f32, _: f32) -> bool {
        true
    }
}

/// What every ray-tracing backend offers (the built-in BVH, Embree later).
pub trait Accelerator: Send + Sync {
    fn intersect(&self, ray: &Ray, filter: &dyn HitFilter) -> Option<Hit>;
    fn occluded(&self, ray: &Ray, filter: &dyn HitFilter) -> bool;
    fn bounds(&self) -> Aabb;
    /// One line on the structure built (sizes, SAH cost), for benchmarks; `None` where the
    /// backend does not expose it.
    fn describe(&self) -> Option<String> {
        None
    }
}

/// Offset for spawning rays off a surface at `p`: scales with the coordinate magnitude,
/// since f32 intersection error does.
#[inline]
pub fn ray_epsilon(p: Vec3) -> f32 {
    (1.0 + p.abs().max_component()) * (1.0 / 65536.0)
}

/// Origin moved off the surface along the geometric normal, to the side `d` points to.
#[inline]
pub fn offset_origin(p: Vec3, ng: Vec3, d: Vec3) -> Vec3 {
    let eps = ray_epsilon(p);
    if ng.dot(d) >= 0.0 {
        p + ng * eps
    } else {
        p - ng * eps
    }
}
