//! The one visibility seam: every shadow test of a connection (next-event estimation, the
//! (s, t) joins, the resampling tables' visibility) is built and answered here, and nowhere
//! else (primary and extension rays are not connections and trace the scene directly).
//! Today every connection is answered by [`ShadowRays`] through the free functions below; the
//! first estimator that answers another way (`vpl`'s skeleton shadow maps, issue 57) passes
//! its [`Visibility`] or [`GroupVisibility`] to the strategies in their place.
//!
//! Two kinds of question:
//! - **pairwise** ([`Visibility`]): is this segment unoccluded? [`ShadowRays`] answers it
//!   exactly with a shadow ray; [`NoShadows`] says yes to everything (the shadowless
//!   estimates of thesis §4.4, the resampling estimators' unoccluded distribution U);
//! - **grouped** ([`GroupVisibility`]): one factor for every light vertex of a group seen
//!   from one view sample, so that a many-light estimator skips all the VPLs of a skeleton
//!   node at once (thesis eq. 161: a node not visible from the view sample's node hides its
//!   VPLs) or takes a visibility cluster's list (ch. 7). A group that cannot be answered as a
//!   whole answers [`GroupAnswer::PerVertex`], and its vertices are asked pairwise.
//!
//! The free functions below build the shadow rays the strategies cast (their origins offset
//! off surfaces, emitter planes and the lens) and answer them with [`ShadowRays`].

use super::vertex::{Vertex, VertexKind};
use crate::geometry::{offset_origin, Ray};
use crate::math::Vec3;
use crate::scene::{Scene, SurfaceInteraction};

/// A pairwise visibility query.
pub trait Visibility: Sync {
    /// Whether nothing blocks `ray` before its `tmax`.
    fn unoccluded(&self, scene: &Scene, ray: &Ray) -> bool;
}

/// Exact: a shadow ray through the scene's BVH.
#[derive(Clone, Copy, Debug, Default)]
pub struct ShadowRays;

impl Visibility for ShadowRays {
    #[inline]
    fn unoccluded(&self, scene: &Scene, ray: &Ray) -> bool {
        !scene.occluded(ray)
    }
}

/// None: every segment is visible (shadowless estimates; biased on purpose where used).
#[derive(Clone, Copy, Debug, Default)]
pub struct NoShadows;

impl Visibility for NoShadows {
    #[inline]
    fn unoccluded(&self, _: &Scene, _: &Ray) -> bool {
        true
    }
}

/// What a grouped query says of a group of light vertices seen from one view sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GroupAnswer {
    /// This factor applies to every vertex of the group (0: all hidden; 1: all visible).
    Factor(f32),
    /// The group cannot be answered as a whole: ask [`Visibility`] vertex by vertex.
    PerVertex,
}

/// A grouped visibility query: `group` names a set of light vertices (a skeleton node's
/// VPLs, a visibility cluster), `view` the vertex they would be joined to.
pub trait GroupVisibility: Sync {
    fn group(&self, scene: &Scene, view: &Vertex, group: u32) -> GroupAnswer;
}

/// Groups are never answered whole: every vertex gets its own shadow ray.
impl GroupVisibility for ShadowRays {
    #[inline]
    fn group(&self, _: &Scene, _: &Vertex, _: u32) -> GroupAnswer {
        GroupAnswer::PerVertex
    }
}

/// Where a shadow ray towards `to` leaves vertex `v`: off its surface, or off an emitter's or
/// the lens's plane, or from the point itself (point lights).
fn shadow_origin(v: &Vertex, to: Vec3) -> Vec3 {
    if v.kind == VertexKind::Surface {
        v.si.spawn_ray_to(to).o
    } else if v.n().length_squared() > 0.0 {
        offset_origin(v.p(), v.n(), to - v.p())
    } else {
        v.p()
    }
}

/// Shadow ray between two vertices (either may be a point light or the lens).
#[inline]
pub fn visible(scene: &Scene, a: &Vertex, b: &Vertex) -> bool {
    let o = shadow_origin(a, b.p());
    let q = shadow_origin(b, o);
    ShadowRays.unoccluded(scene, &Ray { o, d: q - o, tmax: 1.0 - 1e-4 })
}

/// Shadow ray from the point where a connection to the lens crosses the near plane to light
/// vertex `y`: cast from the plane itself (not offset), so that the margin that keeps a
/// shadow ray off its own surfaces falls at `y`'s end and occluders just beyond the plane
/// block it, as they block camera rays starting there.
#[inline]
pub fn visible_from_near_plane(scene: &Scene, near_point: Vec3, y: &Vertex) -> bool {
    let q = shadow_origin(y, near_point);
    ShadowRays.unoccluded(scene, &Ray { o: near_point, d: q - near_point, tmax: 1.0 - 1e-4 })
}

/// Where a shadow ray from a surface ends: at a point (a light's, a skeleton node's), or
/// along a direction out of the scene (an infinite light).
#[derive(Clone, Copy, Debug)]
pub enum ShadowEnd {
    Point(Vec3),
    Direction(Vec3),
}

impl ShadowEnd {
    /// The end of a light sample `ls`: its point, or its direction for an infinite light.
    #[inline]
    pub fn of_light(p: Vec3, wi: Vec3, infinite: bool) -> ShadowEnd {
        if infinite {
            ShadowEnd::Direction(wi)
        } else {
            ShadowEnd::Point(p)
        }
    }
}

/// Shadow ray from surface point `si` to `end`: next-event estimation's test, and a light
/// vertex's view of a skeleton node.
#[inline]
pub fn light_visible(scene: &Scene, si: &SurfaceInteraction, end: ShadowEnd) -> bool {
    let shadow = match end {
        ShadowEnd::Point(p) => si.spawn_ray_to(p),
        ShadowEnd::Direction(wi) => si.spawn_ray(wi),
    };
    ShadowRays.unoccluded(scene, &shadow)
}
