//! The CPU scene flattened into the storage buffers the kernels read: triangles, a binary BVH
//! (bvh.rs), materials, emitting
//! triangles with their pick probabilities, and the camera. A scene outside the feature
//! subset is refused with what is outside it: the GPU never renders a silently different
//! image.

use bytemuck::{Pod, Zeroable};
use skelight::color::Rgb;
use skelight::film::Filter;
use skelight::light::Light;
use skelight::material::microfacet::{Microfacet, MicrofacetType};
use skelight::material::{Bsdf, Perturbation};
use skelight::math::{vec2, vec3, Vec3};
use skelight::scene::Scene;
use skelight::texture::Texture;

use crate::bvh::{build_bvh, Node};
use crate::tables::{constant_value, Tables};
use crate::GpuError;

pub const NONE: u32 = u32::MAX;
/// `Tri::flags`: the triangle has vertex normals; its material has an opacity mask.
pub const SMOOTH: u32 = 1;
pub const MASKED: u32 = 2;
/// `Emitter::tri` of a directional light.
pub const DISTANT: u32 = u32::MAX - 1;
/// `Emitter::tri` of a constant environment.
pub const ENVIRONMENT: u32 = u32::MAX - 2;

/// Four-float attributes per triangle in [`Flat::attributes`].
pub const ATTRIBUTES: usize = 6;

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable, Debug)]
pub struct Tri {
    pub v0: [f32; 3],
    pub material: u32,
    pub v1: [f32; 3],
    pub emitter: u32,
    pub v2: [f32; 3],
    /// 1: shading normals in [`Flat::normals`].
    pub flags: u32,
}

/// Material kinds (`kind` in common.wgsl).
pub const DIFFUSE: u32 = 0;
pub const CONDUCTOR: u32 = 1;
pub const DIELECTRIC: u32 = 2;
pub const ROUGH_CONDUCTOR: u32 = 3;
pub const PLASTIC: u32 = 4;
pub const ROUGH_PLASTIC: u32 = 5;
pub const PHONG: u32 = 6;
pub const ROUGH_DIFFUSE: u32 = 7;
pub const COATED_DIFFUSE: u32 = 8;
pub const ROUGH_DIELECTRIC: u32 = 9;

/// Material flags.
pub const TWO_SIDED: u32 = 1;
pub const BECKMANN: u32 = 2;
pub const NONLINEAR: u32 = 4;
/// The texture replaces the specular colour (`transmittance`) rather than the main one.
pub const TEXTURED_SPECULAR: u32 = 8;

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable, Debug, PartialEq)]
pub struct Material {
    /// Diffuse reflectance, or the specular reflectance of a conductor or dielectric.
    pub reflectance: [f32; 3],
    /// [`TWO_SIDED`], [`BECKMANN`], [`NONLINEAR`].
    pub flags: u32,
    /// A conductor's η per channel; a dielectric's interior over exterior index in x; a
    /// plastic's (η, internal diffuse reflectance, specular sampling weight); Phong's
    /// specular sampling weight in x.
    pub eta: [f32; 3],
    pub kind: u32,
    /// A conductor's absorption k per channel.
    pub k: [f32; 3],
    /// Microfacet roughness α, Phong's exponent, Oren–Nayar's σ.
    pub alpha: f32,
    /// A dielectric's specular transmittance; a plastic's or Phong's specular reflectance.
    pub transmittance: [f32; 3],
    /// A rough plastic's transmittance table: its first entry in [`Flat::data`].
    pub table: u32,
    /// The texture of `reflectance` (a descriptor in [`Flat::data`]), or [`NONE`].
    pub texture: u32,
    /// A bump map's height texture, or [`NONE`].
    pub bump: u32,
    pub bump_scale: f32,
    /// The opacity mask's texture (its channel mean is the opacity), or [`NONE`]: opaque.
    pub mask: u32,
}

impl Default for Material {
    fn default() -> Material {
        Material {
            reflectance: [0.0; 3],
            flags: 0,
            eta: [0.0; 3],
            kind: DIFFUSE,
            k: [0.0; 3],
            alpha: 0.0,
            transmittance: [0.0; 3],
            table: 0,
            texture: NONE,
            bump: NONE,
            bump_scale: 0.0,
            mask: NONE,
        }
    }
}

/// An emitting triangle, a point or spot light (`tri` = [`NONE`]; a point light is a spot
/// whose cone is the whole sphere, `cos_cutoff` = −1), a directional light (`tri` =
/// [`DISTANT`]) or the environment (`tri` = [`ENVIRONMENT`]); the last two start the
/// light pass's rays on a disk (centre `position` for a directional light, the emission
/// sphere's centre for the environment; radius `cutoff`, area `area`).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable, Debug, Default)]
pub struct Emitter {
    /// Radiance of an area light, intensity of a point or spot light.
    pub radiance: [f32; 3],
    pub tri: u32,
    pub position: [f32; 3],
    /// Inclusive cumulative pick probability.
    pub cdf: f32,
    /// A spot's beam axis.
    pub axis: [f32; 3],
    /// Probability of picking this emitter (by power).
    pub pick: f32,
    /// An emitting triangle's area.
    pub area: f32,
    pub cos_cutoff: f32,
    /// A spot's falloff angles (radians).
    pub cutoff: f32,
    pub beam_width: f32,
}

/// The kernels' uniform block (`Params` in common.wgsl), 224 bytes.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable, Debug, Default)]
pub struct Params {
    pub cam_pos: [f32; 4],
    pub cam_x: [f32; 4],
    pub cam_y: [f32; 4],
    pub cam_z: [f32; 4],
    pub inv_x: [f32; 4],
    pub inv_y: [f32; 4],
    pub inv_z: [f32; 4],
    pub forward: [f32; 4],
    pub tan_half: [f32; 2],
    pub near_clip: f32,
    pub eps_scale: f32,
    pub width: u32,
    pub height: u32,
    pub seed_lo: u32,
    pub seed_hi: u32,
    pub first_sample: u32,
    pub samples: u32,
    pub max_depth: i32,
    pub rr_depth: i32,
    pub emitters: u32,
    pub x0: u32,
    pub y0: u32,
    pub bidirectional: u32,
    /// The tent filter's radius in pixels; 0 for the box filter.
    pub filter_radius: f32,
    /// The environment's emitter, or [`NONE`].
    pub environment: u32,
    /// Its lat-long map's descriptor in the data buffer, or [`NONE`] for a constant one.
    pub environment_map: u32,
    /// The thin lens's aperture radius (0: a pinhole) and focus distance.
    pub aperture_radius: f32,
    pub focus_distance: f32,
    /// The dispatch's depth: thread z takes samples z, z + slices, … into film slice z.
    pub slices: u32,
    /// The wavefront camera pass: the group of `slices` samples a wave takes, and the tile
    /// size its path buffers are laid out by.
    pub wave: u32,
    pub wf_tile_w: u32,
    pub wf_tile_h: u32,
    pub pad: [u32; 3],
}

/// Everything the kernels read of a scene.
pub struct Flat {
    pub nodes: Vec<Node>,
    pub tris: Vec<Tri>,
    /// [`ATTRIBUTES`] per triangle: its vertices' normals (zero without shading normals)
    /// with their u in w, their three v, dp/du, dp/dv (for bump maps).
    pub attributes: Vec<[f32; 4]>,
    pub materials: Vec<Material>,
    pub emitters: Vec<Emitter>,
    /// Tables the BSDFs read (rough plastics' transmittance).
    pub data: Vec<f32>,
    /// The camera and settings part of the uniform block (the rest is set per dispatch).
    pub params: Params,
}

/// What the GPU renders today; anything else is refused by [`flatten`].
pub const FEATURES: &str = "BSDFs diffuse, roughdiffuse, conductor, roughconductor, \
    dielectric, roughdielectric, plastic, roughplastic, phong and coating over diffuse, \
    isotropic roughness, \
    one- or two-sided alike, the main colour (or phong's specular one) constant or a bitmap or \
    checkerboard texture; bump maps; opacity masks; area lights on triangle meshes, point, spot and directional lights, a constant or \
    lat-long environment; shading normals; pinhole and thin-lens cameras; box and tent filters. Not yet: exact \
    spheres, normal maps, other BSDFs, sun and sky";

fn unsupported(what: String) -> GpuError {
    GpuError::Unsupported(format!("{what}; the GPU renders {FEATURES}"))
}

/// The material's GPU form (its textures and tables added to `tables`), or why it has none.
fn material(bsdf: &Bsdf, name: &str, tables: &mut Tables) -> Result<Material, GpuError> {
    let constant = |t: &Texture| {
        constant_value(t).ok_or_else(|| unsupported(format!("material '{name}' has a texture other than its colour")))
    };
    // The main colour (`reflectance`) may be a texture.
    let colour = |t: &Texture, tables: &mut Tables| match tables.texture(t) {
        Some(at) => Ok(Material { reflectance: [1.0; 3], texture: at, ..Material::default() }),
        None => Ok(Material { reflectance: constant(t)?, ..Material::default() }),
    };
    let rgb = |c: Rgb| [c.r, c.g, c.b];
    // Isotropic microfacets only (the kernels' local frame has no tangent).
    let microfacet = |d: &Microfacet| {
        if d.alpha_u != d.alpha_v {
            return Err(unsupported(format!("material '{name}' has anisotropic roughness")));
        }
        Ok((d.alpha_u, if d.kind == MicrofacetType::Beckmann { BECKMANN } else { 0 }))
    };
    Ok(match bsdf {
        Bsdf::Diffuse(d) => colour(&d.reflectance, tables)?,
        Bsdf::Black => Material::default(),
        Bsdf::RoughDiffuse(d) => Material { kind: ROUGH_DIFFUSE, alpha: d.alpha, ..colour(&d.reflectance, tables)? },
        Bsdf::Conductor(c) => {
            Material { eta: rgb(c.eta), k: rgb(c.k), kind: CONDUCTOR, ..colour(&c.specular_reflectance, tables)? }
        }
        Bsdf::RoughConductor(c) => {
            let (alpha, flags) = microfacet(&c.distribution)?;
            Material {
                eta: rgb(c.eta),
                k: rgb(c.k),
                kind: ROUGH_CONDUCTOR,
                alpha,
                flags,
                ..colour(&c.specular_reflectance, tables)?
            }
        }
        // Light crosses a dielectric from either side.
        Bsdf::Dielectric(d) => Material {
            reflectance: rgb(d.specular_reflectance),
            transmittance: rgb(d.specular_transmittance),
            eta: [d.eta, 0.0, 0.0],
            kind: DIELECTRIC,
            flags: TWO_SIDED,
            ..Material::default()
        },
        Bsdf::RoughDielectric(d) => {
            let (alpha, flags) = microfacet(&d.distribution)?;
            Material {
                reflectance: rgb(d.specular_reflectance),
                transmittance: rgb(d.specular_transmittance),
                eta: [d.eta, 0.0, 0.0],
                kind: ROUGH_DIELECTRIC,
                alpha,
                flags: flags | TWO_SIDED,
                ..Material::default()
            }
        }
        Bsdf::Plastic(_) | Bsdf::RoughPlastic(_) => {
            let p = match bsdf {
                Bsdf::Plastic(p) => p.parts(),
                Bsdf::RoughPlastic(p) => p.parts(),
                _ => unreachable!(),
            };
            let (alpha, mut flags) = match &p.distribution {
                Some(d) => microfacet(d)?,
                None => (0.0, 0),
            };
            if p.nonlinear {
                flags |= NONLINEAR;
            }
            let table = if p.external_transmittance.is_empty() { 0 } else { tables.push(p.external_transmittance) };
            Material {
                transmittance: constant(p.specular)?,
                eta: [p.eta, p.internal_reflectance, p.specular_weight],
                kind: if p.distribution.is_some() { ROUGH_PLASTIC } else { PLASTIC },
                alpha,
                flags,
                table,
                ..colour(p.diffuse, tables)?
            }
        }
        // Either colour may be a texture (a constant diffuse under a textured specular, as
        // sibenik's floor in the seeds' configuration), not both.
        Bsdf::Phong(p) => match (constant_value(&p.diffuse), tables.texture(&p.specular)) {
            (Some(diffuse), Some(at)) => Material {
                reflectance: diffuse,
                transmittance: [1.0; 3],
                texture: at,
                flags: TEXTURED_SPECULAR,
                eta: [p.specular_weight, 0.0, 0.0],
                alpha: p.exponent,
                kind: PHONG,
                ..Material::default()
            },
            _ => Material {
                transmittance: constant(&p.specular)?,
                eta: [p.specular_weight, 0.0, 0.0],
                alpha: p.exponent,
                kind: PHONG,
                ..colour(&p.diffuse, tables)?
            },
        },
        Bsdf::Coating(c) => match c.nested.as_ref() {
            Bsdf::Diffuse(d) => Material {
                transmittance: rgb(c.specular_reflectance),
                eta: [c.eta, 0.0, c.specular_weight()],
                k: rgb(c.sigma_a_thickness),
                kind: COATED_DIFFUSE,
                ..colour(&d.reflectance, tables)?
            },
            other => {
                return Err(unsupported(format!("material '{name}' is a coating over {}", bsdf_name(other))));
            }
        },
        // The same BSDF on both sides (the back mirrored) is that BSDF, two-sided.
        Bsdf::TwoSided(front, back) => {
            let side = |b: &Bsdf| {
                let mut scratch = Tables::default();
                material(b, name, &mut scratch).map(|m| (m, scratch.data))
            };
            let f = side(front)?;
            if side(back)? != f || f.0.kind == DIELECTRIC || f.0.kind == ROUGH_DIELECTRIC {
                return Err(unsupported(format!("material '{name}' is two-sided with different BSDFs on its sides")));
            }
            let f = material(front, name, tables)?;
            Material { flags: f.flags | TWO_SIDED, ..f }
        }
        other => return Err(unsupported(format!("material '{name}' is {}", bsdf_name(other)))),
    })
}

fn bsdf_name(b: &Bsdf) -> &'static str {
    match b {
        Bsdf::Diffuse(_) => "diffuse",
        Bsdf::RoughDiffuse(_) => "roughdiffuse",
        Bsdf::Conductor(_) => "conductor",
        Bsdf::RoughConductor(_) => "roughconductor",
        Bsdf::Dielectric(_) => "dielectric",
        Bsdf::ThinDielectric(_) => "thindielectric",
        Bsdf::RoughDielectric(_) => "roughdielectric",
        Bsdf::Plastic(_) => "plastic",
        Bsdf::RoughPlastic(_) => "roughplastic",
        Bsdf::Phong(_) => "phong",
        Bsdf::Ward(_) => "ward",
        Bsdf::Coating(_) => "coating",
        Bsdf::TwoSided(..) => "twosided",
        Bsdf::Black => "black",
    }
}

/// The scene's filter, lights and materials in their GPU form: everything but the triangles.
struct Shading {
    filter_radius: f32,
    emitters: Vec<Emitter>,
    /// Each emitter's power (the weight of its pick); the emitting triangles' come later.
    power: Vec<f64>,
    tables: Tables,
    environment_map: u32,
    materials: Vec<Material>,
}

/// Whether the GPU renders `scene`: every refusal of [`flatten`], without copying the
/// triangles or building the BVH (`compare` asks before its first run).
pub fn supported(scene: &Scene) -> Result<(), GpuError> {
    shading(scene)?;
    check_meshes(scene)
}

/// The meshes' refusals: exact spheres that do not emit (the GPU has no sphere
/// intersection; an emitting one is its triangles), and a scene without triangles.
fn check_meshes(scene: &Scene) -> Result<(), GpuError> {
    if let Some(mesh) = scene.meshes.iter().find(|m| m.sphere.is_some() && m.emission.is_none()) {
        return Err(unsupported(format!("mesh '{}' is an exact sphere", mesh.name)));
    }
    if scene.meshes.iter().all(|m| m.indices.is_empty()) {
        return Err(GpuError::Unsupported("the scene has no triangles".into()));
    }
    Ok(())
}

/// The filter, lights and materials, or why the GPU cannot render them.
fn shading(scene: &Scene) -> Result<Shading, GpuError> {
    let s = &scene.settings;
    let filter_radius = match s.filter {
        Filter::Box => 0.0,
        Filter::Tent { radius } => radius,
        other => return Err(unsupported(format!("the film's filter is {other:?}"))),
    };
    // Point, spot and directional lights; area lights come with their meshes' triangles below.
    let mut emitters = Vec::new();
    let mut power = Vec::new();
    let mut tables = Tables::default();
    let mut environment_map = NONE;
    // Distant lights start the light pass's rays on a disk of the emission sphere's radius
    // (the CPU's sample_le): its centre, radius and area.
    let (sphere_center, disk_radius) = scene.emission_sphere();
    let disk_area = std::f32::consts::PI * disk_radius * disk_radius;
    for light in &scene.lights {
        let rgb = |c: Rgb| [c.r, c.g, c.b];
        let p = |v: Vec3| [v.x, v.y, v.z];
        let (emitter, solid_angle) = match *light {
            Light::Area(_) => continue,
            Light::Point { position, intensity } => {
                let e = Emitter {
                    radiance: rgb(intensity),
                    tri: NONE,
                    position: p(position),
                    axis: [0.0, 0.0, 1.0],
                    cos_cutoff: -1.0,
                    ..Emitter::default()
                };
                (e, 4.0 * std::f64::consts::PI)
            }
            Light::Spot { position, frame, intensity, cos_cutoff, cutoff, beam_width } => {
                let e = Emitter {
                    radiance: rgb(intensity),
                    tri: NONE,
                    position: p(position),
                    axis: p(frame.n),
                    cos_cutoff,
                    cutoff,
                    beam_width,
                    ..Emitter::default()
                };
                (e, 2.0 * std::f64::consts::PI * (1.0 - cos_cutoff as f64))
            }
            Light::Directional { direction, irradiance } => {
                // The disk behind the scene, perpendicular to the direction.
                let e = Emitter {
                    radiance: rgb(irradiance),
                    tri: DISTANT,
                    position: p(sphere_center - direction * disk_radius),
                    axis: p(direction),
                    area: disk_area,
                    cutoff: disk_radius,
                    ..Emitter::default()
                };
                // "Power" as irradiance × the disk's area (the pick's weight only).
                (e, disk_area as f64)
            }
            Light::Constant { .. } | Light::Env(_) => {
                if emitters.iter().any(|e: &Emitter| e.tri == ENVIRONMENT) {
                    return Err(unsupported("the scene has two environment lights".into()));
                }
                // The radiance: the constant's, or a map's mean (for the pick's weight only;
                // environment.wgsl reads the map).
                let radiance = match light {
                    Light::Env(env) => {
                        let Some(map) = env.as_lat_long() else {
                            return Err(unsupported("the scene has a sun and sky".into()));
                        };
                        environment_map = tables.environment_map(map);
                        map.image().mean() * map.scale()
                    }
                    Light::Constant { radiance } => *radiance,
                    _ => unreachable!(),
                };
                let e = Emitter {
                    radiance: rgb(radiance),
                    tri: ENVIRONMENT,
                    position: p(sphere_center),
                    area: disk_area,
                    cutoff: disk_radius,
                    ..Emitter::default()
                };
                // As the CPU's power: π × the disk's area × radiance.
                (e, std::f64::consts::PI * disk_area as f64)
            }
        };
        emitters.push(emitter);
        power.push(
            solid_angle
                * Rgb { r: emitter.radiance[0], g: emitter.radiance[1], b: emitter.radiance[2] }.luminance() as f64,
        );
    }
    let mut materials = Vec::new();
    for m in &scene.materials {
        let mut flat = material(&m.bsdf, &m.name, &mut tables)?;
        match &m.perturbation {
            None => {}
            Some(Perturbation::Bump { height, scale }) => {
                // A constant height has no gradient: no bump at all.
                if let Some(at) = tables.texture(height) {
                    flat.bump = at;
                    flat.bump_scale = *scale;
                }
            }
            Some(Perturbation::NormalMap { .. }) => {
                return Err(unsupported(format!("material '{}' has a normal map", m.name)));
            }
        }
        materials.push(flat);
    }
    Ok(Shading { filter_radius, emitters, power, tables, environment_map, materials })
}

/// The scene in the kernels' buffers: [`shading`], the triangles in the BVH's order with
/// their attributes, the emitters' pick table, the camera and settings.
pub fn flatten(scene: &Scene) -> Result<Flat, GpuError> {
    let Shading { filter_radius, mut emitters, mut power, mut tables, environment_map, mut materials } =
        shading(scene)?;
    check_meshes(scene)?;
    let (s, cam) = (&scene.settings, &scene.camera);
    let mut tris = Vec::new();
    let mut attributes = Vec::new();
    let mut emitting: Vec<(u32, Rgb, f32)> = Vec::new();
    for mesh in &scene.meshes {
        // A masked mesh gets its own copy of its material, carrying the mask.
        let mut material = mesh.material;
        if let Some(alpha) = &mesh.alpha {
            let mask = tables.texture(alpha).unwrap_or_else(|| tables.constant_texture(constant_value(alpha)));
            materials.push(Material { mask, ..materials[mesh.material as usize] });
            material = materials.len() as u32 - 1;
        }
        for i in 0..mesh.indices.len() {
            let [a, b, c] = mesh.triangle(i);
            let area = 0.5 * (b - a).cross(c - a).length();
            let mut emitter = NONE;
            if let Some(l) = mesh.emission.filter(|l| l.max_component() > 0.0 && area > 0.0) {
                emitter = (emitters.len() + emitting.len()) as u32;
                emitting.push((tris.len() as u32, l, area));
            }
            let p = |v: Vec3| [v.x, v.y, v.z];
            let smooth = !mesh.normals.is_empty();
            let flags = if smooth { SMOOTH } else { 0 } | if mesh.alpha.is_some() { MASKED } else { 0 };
            tris.push(Tri { v0: p(a), material, v1: p(b), emitter, v2: p(c), flags });
            // Without texture coordinates uv are the barycentrics (as the CPU's uv_at).
            let corners = [vec2(0.0, 0.0), vec2(1.0, 0.0), vec2(0.0, 1.0)];
            let uv = |j: usize| if mesh.uvs.is_empty() { corners[j] } else { mesh.uvs[mesh.indices[i][j] as usize] };
            for (j, k) in mesh.indices[i].into_iter().enumerate() {
                let n = if smooth { mesh.normals[k as usize] } else { Vec3::ZERO };
                attributes.push([n.x, n.y, n.z, uv(j).x]);
            }
            attributes.push([uv(0).y, uv(1).y, uv(2).y, 0.0]);
            let (dpdu, dpdv) = mesh.position_derivatives(i);
            attributes.push([dpdu.x, dpdu.y, dpdu.z, 0.0]);
            attributes.push([dpdv.x, dpdv.y, dpdv.z, 0.0]);
        }
    }
    // Emitting triangles by power (π × area × luminance of their radiance), after the others.
    for &(tri, radiance, area) in &emitting {
        power.push(std::f64::consts::PI * area as f64 * radiance.luminance() as f64);
        emitters.push(Emitter { radiance: [radiance.r, radiance.g, radiance.b], tri, area, ..Emitter::default() });
    }
    let total: f64 = power.iter().sum();
    let mut acc = 0.0;
    for (e, &w) in emitters.iter_mut().zip(&power) {
        acc += w;
        e.cdf = (acc / total) as f32;
        e.pick = (w / total) as f32;
    }
    if let Some(last) = emitters.last_mut() {
        last.cdf = 1.0;
    }
    let (nodes, order) = build_bvh(&tris);
    let tris: Vec<Tri> = order.iter().map(|&i| tris[i as usize]).collect();
    let attributes: Vec<[f32; 4]> = order
        .iter()
        .flat_map(|&i| attributes[ATTRIBUTES * i as usize..ATTRIBUTES * (i as usize + 1)].to_vec())
        .collect();
    // Where each triangle went in the BVH's order (an inverse permutation, not a search per
    // emitter: scenes with many emitting triangles would take quadratic time).
    let mut position = vec![0u32; order.len()];
    for (at, &i) in order.iter().enumerate() {
        position[i as usize] = at as u32;
    }
    for e in emitters.iter_mut().filter(|e| e.tri < ENVIRONMENT) {
        e.tri = position[e.tri as usize];
    }
    let v = |x: Vec3| [x.x, x.y, x.z, 0.0];
    let axis = |d: Vec3| v(cam.to_world.vector(d));
    let to_local = cam.to_world.inverse();
    let local = |d: Vec3| v(to_local.vector(d));
    let params = Params {
        cam_pos: v(cam.position),
        cam_x: axis(vec3(1.0, 0.0, 0.0)),
        cam_y: axis(vec3(0.0, 1.0, 0.0)),
        cam_z: axis(vec3(0.0, 0.0, 1.0)),
        inv_x: local(vec3(1.0, 0.0, 0.0)),
        inv_y: local(vec3(0.0, 1.0, 0.0)),
        inv_z: local(vec3(0.0, 0.0, 1.0)),
        forward: v(cam.forward),
        tan_half: [cam.tan_half.x, cam.tan_half.y],
        near_clip: cam.near_clip,
        aperture_radius: cam.aperture_radius.max(0.0),
        focus_distance: cam.focus_distance,
        // As the CPU's ray_epsilon.
        eps_scale: 1.0 / 65536.0,
        width: s.width as u32,
        height: s.height as u32,
        max_depth: s.max_depth,
        rr_depth: s.rr_depth as i32,
        emitters: emitters.len() as u32,
        filter_radius,
        environment: emitters.iter().position(|e| e.tri == ENVIRONMENT).map_or(NONE, |i| i as u32),
        environment_map,
        ..Params::default()
    };
    Ok(Flat { nodes, tris, attributes, materials, emitters, data: tables.data, params })
}
