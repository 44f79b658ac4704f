//! skelight's own scene file (TOML): places OBJ/PLY meshes, overrides their materials by
//! name, and adds a camera and lights — for meshes that come without them (the seeds'
//! Sibenik configuration, the raw corridor OBJ). Paths are relative to the TOML file and
//! may point outside its folder: this file is the user's own assembly of existing data.
//!
//! ```toml
//! [film]       # width, height, spp, filter = "box" | "tent" | "gaussian"
//! [integrator] # max_depth, rr_depth
//! [camera]     # origin, target, up, fov, fov_axis, aperture_radius, focus_distance
//! [[mesh]]     # file, face_normals, transform = { translate, scale, rotate = [x, y, z, degrees] }
//!              # file may also be a Mitsuba scene (.xml): its shapes and materials (BSDF ids
//!              # are the names overrides match); its camera, film and lights are not taken,
//!              # and with drop_emitters = true neither are its emissive shapes
//! [mesh.materials.NAME]  # type = "diffuse" | "phong" | "mirror" | "glass", color, texture,
//!                        # specular, specular_texture, exponent, ior, two_sided,
//!                        # raw_textures (stored values are linear, not sRGB; nearest lookup)
//! [[light]]    # type = "disk" | "quad" | "sphere" | "point" | "spot" | "directional" | "constant"
//! ```

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde::Deserialize;

use super::obj::{load_obj, MtlMaterial};
use super::LoadError;
use crate::camera::{Camera, FovAxis, Lens};
use crate::color::Rgb;
use crate::film::Filter;
use crate::imageio::Image;
use crate::light::Light;
use crate::material::{Bsdf, Conductor, Dielectric, Diffuse, Material, Perturbation, Phong};
use crate::math::{vec3, Frame, Transform, Vec3};
use crate::scene::shapes::{self, TriangleData};
use crate::scene::{RenderSettings, SceneDescription};
use crate::texture::{Bitmap, TexFilter, Texture, UvTransform};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct NativeScene {
    film: Option<FilmSection>,
    integrator: Option<IntegratorSection>,
    camera: Option<CameraSection>,
    #[serde(default)]
    mesh: Vec<MeshSection>,
    #[serde(default)]
    light: Vec<LightSection>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FilmSection {
    width: Option<usize>,
    height: Option<usize>,
    spp: Option<u32>,
    filter: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct IntegratorSection {
    max_depth: Option<i32>,
    rr_depth: Option<u32>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraSection {
    origin: [f64; 3],
    target: [f64; 3],
    up: Option<[f64; 3]>,
    fov: Option<f32>,
    fov_axis: Option<String>,
    aperture_radius: Option<f32>,
    focus_distance: Option<f32>,
    /// Camera-space depth below which nothing is seen (default: Mitsuba's 0.01).
    near_clip: Option<f32>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct TransformSection {
    translate: Option<[f64; 3]>,
    scale: Option<[f64; 3]>,
    /// Axis x, y, z and angle in degrees.
    rotate: Option<[f64; 4]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MeshSection {
    file: String,
    #[serde(default)]
    face_normals: bool,
    transform: Option<TransformSection>,
    /// Material overrides by MTL name (a Mitsuba file: BSDF id); "*" applies to all.
    #[serde(default)]
    materials: HashMap<String, MaterialSection>,
    /// A Mitsuba file's emissive shapes are left out (its other lights always are).
    #[serde(default)]
    drop_emitters: bool,
}

#[derive(Deserialize, Clone, Copy)]
#[serde(untagged)]
enum Color {
    Grey(f32),
    Rgb([f32; 3]),
}

impl Color {
    fn rgb(self) -> Rgb {
        match self {
            Color::Grey(v) => Rgb::splat(v),
            Color::Rgb(a) => Rgb::from_array(a),
        }
    }
}

#[derive(Deserialize, Clone)]
#[serde(deny_unknown_fields)]
struct MaterialSection {
    #[serde(rename = "type")]
    kind: String,
    color: Option<Color>,
    /// Bitmap for the diffuse colour (phong: also for the specular colour if `specular_texture`).
    texture: Option<String>,
    specular: Option<Color>,
    specular_texture: Option<String>,
    exponent: Option<f32>,
    ior: Option<f32>,
    /// Shade both sides alike (real meshes often have inconsistent winding).
    #[serde(default)]
    two_sided: bool,
    /// The textures' bytes are linear reflectances (byte / 255), looked up nearest-neighbour,
    /// as some renderers read them (the pg2015 authors' Bonez), rather than sRGB, bilinearly.
    #[serde(default)]
    raw_textures: bool,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LightSection {
    #[serde(rename = "type")]
    kind: String,
    position: Option<[f32; 3]>,
    normal: Option<[f32; 3]>,
    direction: Option<[f32; 3]>,
    target: Option<[f32; 3]>,
    radius: Option<f32>,
    size: Option<[f32; 2]>,
    radiance: Option<Color>,
    intensity: Option<Color>,
    irradiance: Option<Color>,
    cutoff_angle: Option<f32>,
    beam_width: Option<f32>,
}

struct Ctx<'a> {
    path: &'a Path,
    dir: PathBuf,
    /// Decoded bitmaps by path and whether they are raw.
    bitmaps: HashMap<(PathBuf, bool), Arc<Bitmap>>,
}

impl Ctx<'_> {
    fn err(&self, msg: impl Into<String>) -> LoadError {
        LoadError::at(self.path, 0, msg.into())
    }
    fn bitmap(&mut self, base: &Path, name: &str) -> Result<Texture, LoadError> {
        self.bitmap_as(base, name, false)
    }

    /// `raw`: linear values, nearest lookup (see `raw_textures`); otherwise sRGB, bilinear.
    fn bitmap_as(&mut self, base: &Path, name: &str, raw: bool) -> Result<Texture, LoadError> {
        let key = (base.join(name), raw);
        if let Some(b) = self.bitmaps.get(&key) {
            return Ok(Texture::Bitmap { bitmap: b.clone(), to_uv: UvTransform::IDENTITY });
        }
        let img = Image::load(&key.0).map_err(|e| self.err(e.to_string()))?;
        let filter = if raw { TexFilter::Nearest } else { TexFilter::Bilinear };
        let b = Arc::new(Bitmap::new(img, !raw, filter));
        self.bitmaps.insert(key, b.clone());
        Ok(Texture::Bitmap { bitmap: b, to_uv: UvTransform::IDENTITY })
    }
}

fn unit(v: [f32; 3]) -> Option<Vec3> {
    let v = vec3(v[0], v[1], v[2]);
    (v.length() > 0.0 && v.is_finite()).then(|| v.normalize())
}

/// A bare OBJ or PLY file as a scene: its own materials, a camera framing it, and a
/// uniform sky (with a warning) when nothing in it emits light.
pub fn load_mesh_file(path: &Path) -> Result<SceneDescription, LoadError> {
    let mut ctx = Ctx { path, dir: path.parent().unwrap_or(Path::new(".")).to_path_buf(), bitmaps: HashMap::new() };
    let mut desc = SceneDescription::default();
    let name = path.file_name().map(|n| n.to_string_lossy().to_string()).unwrap_or_default();
    let section = MeshSection {
        file: name,
        face_normals: false,
        transform: None,
        materials: HashMap::new(),
        drop_emitters: false,
    };
    load_mesh(&mut ctx, &section, &mut desc)?;
    if desc.meshes.iter().all(|m| m.emission.is_none()) {
        desc.warnings
            .push(format!("{}: no emitters; lit by a uniform white sky so that it is visible", path.display()));
        desc.lights.push(Light::Constant { radiance: Rgb::WHITE });
    }
    desc.settings = RenderSettings { filter: Filter::Box, ..RenderSettings::default() };
    Ok(desc)
}

pub fn load_native(path: &Path) -> Result<SceneDescription, LoadError> {
    let text = super::read_text(path)?;
    let doc: NativeScene = toml::from_str(&text).map_err(|e| {
        let line = e.span().map(|s| text[..s.start].lines().count().max(1)).unwrap_or(0);
        LoadError::at(path, line, e.message().to_string())
    })?;
    let mut ctx = Ctx { path, dir: path.parent().unwrap_or(Path::new(".")).to_path_buf(), bitmaps: HashMap::new() };
    let mut desc = SceneDescription::default();
    let mut settings = RenderSettings { filter: Filter::Box, ..RenderSettings::default() };
    if let Some(f) = doc.film {
        settings.width = f.width.unwrap_or(settings.width);
        settings.height = f.height.unwrap_or(settings.height);
        crate::scene::check_resolution(settings.width as i64, settings.height as i64).map_err(|m| ctx.err(m))?;
        settings.spp = f.spp.unwrap_or(settings.spp);
        if settings.spp == 0 {
            return Err(ctx.err("film.spp must be at least 1"));
        }
        settings.filter = match f.filter.as_deref().unwrap_or("box") {
            "box" => Filter::Box,
            "tent" => Filter::Tent { radius: 1.0 },
            "gaussian" => Filter::Gaussian { stddev: 0.5 },
            other => return Err(ctx.err(format!("unknown filter '{other}' (box, tent or gaussian)"))),
        };
    }
    if let Some(i) = doc.integrator {
        settings.max_depth = i.max_depth.unwrap_or(-1);
        settings.rr_depth = i.rr_depth.unwrap_or(5);
    }
    for m in &doc.mesh {
        load_mesh(&mut ctx, m, &mut desc)?;
    }
    for l in &doc.light {
        add_light(&ctx, l, &mut desc)?;
    }
    if let Some(c) = doc.camera {
        let axis = match c.fov_axis.as_deref().unwrap_or("x") {
            "x" => FovAxis::X,
            "y" => FovAxis::Y,
            other => return Err(ctx.err(format!("unknown fov_axis '{other}' (x or y)"))),
        };
        let t = Transform::look_at(c.origin, c.target, c.up.unwrap_or([0.0, 1.0, 0.0]))
            .ok_or_else(|| ctx.err("camera: origin equals target, or up is parallel to the view"))?;
        let fov = c.fov.unwrap_or(45.0);
        if !(fov > 0.0 && fov < 180.0) {
            return Err(ctx.err(format!("camera.fov {fov} must lie in (0, 180)")));
        }
        let lens =
            Lens { aperture_radius: c.aperture_radius.unwrap_or(0.0), focus_distance: c.focus_distance.unwrap_or(1.0) };
        let Lens { aperture_radius: aperture, focus_distance: focus } = lens;
        if !(aperture >= 0.0 && aperture.is_finite()) {
            return Err(ctx.err(format!("camera.aperture_radius {aperture} must be finite and at least 0")));
        }
        if aperture > 0.0 && !(focus > 0.0 && focus.is_finite()) {
            return Err(ctx.err(format!("camera.focus_distance {focus} must be finite and positive for a thin lens")));
        }
        let near = c.near_clip.unwrap_or(Camera::DEFAULT_NEAR_CLIP);
        if !(near >= 0.0 && near.is_finite()) {
            return Err(ctx.err(format!("camera.near_clip {near} must be finite and at least 0")));
        }
        desc.camera = Some(Camera::new(t, settings.width, settings.height, fov, axis, lens, near));
    }
    desc.settings = settings;
    Ok(desc)
}

fn transform_of(t: &Option<TransformSection>) -> Option<Transform> {
    let Some(t) = t else { return Some(Transform::IDENTITY) };
    let mut acc = Transform::IDENTITY;
    if let Some(s) = t.scale {
        acc = Transform::scale(s)?.compose(&acc);
    }
    if let Some([x, y, z, deg]) = t.rotate {
        acc = Transform::rotate([x, y, z], deg)?.compose(&acc);
    }
    if let Some(d) = t.translate {
        acc = Transform::translate(d).compose(&acc);
    }
    Some(acc)
}

/// Material for an MTL entry: emissive Ke, Phong when Ks and Ns are set, diffuse otherwise;
/// `d` < 1 or `map_d` becomes an opacity mask, `map_bump` a bump map.
fn mtl_material(
    ctx: &mut Ctx,
    base: &Path,
    m: &MtlMaterial,
) -> Result<(Material, Option<Texture>, Option<Rgb>), LoadError> {
    // An MTL's maps stay in its OBJ's folder, whoever names the OBJ.
    let map = |ctx: &mut Ctx, f: &str| -> Result<Texture, LoadError> {
        let p = super::confined_file(base, base, f)
            .map_err(|e| ctx.err(format!("material '{}', texture '{f}': {e}", m.name)))?;
        ctx.bitmap(Path::new(""), &p.to_string_lossy())
    };
    let kd = match &m.map_kd {
        Some(f) => map(ctx, f)?,
        None => Texture::Constant(m.kd.unwrap_or(Rgb::splat(0.5))),
    };
    let ks = m.ks.unwrap_or(Rgb::BLACK);
    let bsdf = if ks.max_component() > 0.0 && m.ns.unwrap_or(0.0) > 0.0 {
        Bsdf::Phong(Phong::new(kd, Texture::Constant(ks), m.ns.unwrap_or(1.0)))
    } else {
        Bsdf::Diffuse(Diffuse { reflectance: kd })
    };
    let mut mat = Material::new(m.name.clone(), bsdf);
    if let Some(b) = &m.map_bump {
        mat.perturbation = Some(Perturbation::Bump { height: map(ctx, b)?, scale: 1.0 });
    }
    let alpha = match (&m.map_d, m.d) {
        (Some(f), _) => Some(map(ctx, f)?),
        (None, Some(d)) if d < 1.0 => Some(Texture::constant(d.max(0.0))),
        _ => None,
    };
    let emission = m.ke.filter(|k| k.max_component() > 0.0);
    Ok((mat, alpha, emission))
}

fn override_material(ctx: &mut Ctx, name: &str, o: &MaterialSection) -> Result<Material, LoadError> {
    let dir = ctx.dir.clone();
    let color = match &o.texture {
        Some(f) => ctx.bitmap_as(&dir, f, o.raw_textures)?,
        None => Texture::Constant(o.color.map(Color::rgb).unwrap_or(Rgb::splat(0.5))),
    };
    let bsdf = match o.kind.as_str() {
        "diffuse" => Bsdf::Diffuse(Diffuse { reflectance: color }),
        "phong" => {
            let spec = match &o.specular_texture {
                Some(f) => ctx.bitmap_as(&dir, f, o.raw_textures)?,
                None => Texture::Constant(o.specular.map(Color::rgb).unwrap_or(Rgb::splat(0.2))),
            };
            Bsdf::Phong(Phong::new(color, spec, o.exponent.unwrap_or(30.0)))
        }
        "mirror" => Bsdf::Conductor(Conductor { eta: Rgb::BLACK, k: Rgb::WHITE, specular_reflectance: color }),
        "glass" => Bsdf::Dielectric(Dielectric {
            eta: o.ior.unwrap_or(1.5),
            specular_reflectance: Rgb::WHITE,
            specular_transmittance: Rgb::WHITE,
        }),
        other => {
            return Err(ctx.err(format!("material '{name}': unknown type '{other}' (diffuse, phong, mirror, glass)")))
        }
    };
    let bsdf = if o.two_sided { Bsdf::TwoSided(Box::new(bsdf.clone()), Box::new(bsdf)) } else { bsdf };
    Ok(Material::new(name, bsdf))
}

/// Triangles of one MTL material (None: no `usemtl`).
type NamedGroup = (Option<String>, TriangleData);

fn load_mesh(ctx: &mut Ctx, m: &MeshSection, desc: &mut SceneDescription) -> Result<(), LoadError> {
    let file = ctx.dir.join(&m.file);
    let t = transform_of(&m.transform).ok_or_else(|| ctx.err(format!("mesh '{}': singular transform", m.file)))?;
    let ext = file.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    let base = file.parent().unwrap_or(Path::new(".")).to_path_buf();
    let (groups, mtl): (Vec<NamedGroup>, HashMap<String, MtlMaterial>) = match ext.as_str() {
        "obj" => {
            let obj = load_obj(&file)?;
            let mtl = obj.materials.into_iter().map(|x| (x.name.clone(), x)).collect();
            (obj.groups.into_iter().map(|g| (g.material, g.data)).collect(), mtl)
        }
        "ply" => (vec![(None, super::ply::load_ply(&file)?)], HashMap::new()),
        "xml" => return load_mitsuba_shapes(ctx, m, &file, desc),
        other => return Err(ctx.err(format!("mesh '{}': unsupported format '.{other}' (obj, ply or xml)", m.file))),
    };
    if m.drop_emitters {
        return Err(ctx.err(format!("mesh '{}': drop_emitters applies to Mitsuba (.xml) files", m.file)));
    }
    let names: Vec<String> = groups.iter().map(|(n, _)| n.clone().unwrap_or_default()).collect();
    warn_unused_overrides(m, &names, desc);
    for (name, data) in groups {
        let key = name.clone().unwrap_or_default();
        let (material, alpha, emission) = match m.materials.get(&key).or_else(|| m.materials.get("*")) {
            Some(o) => (override_material(ctx, &key, o)?, None, None),
            None => match mtl.get(&key) {
                Some(x) => mtl_material(ctx, &base, x)?,
                None => (
                    Material::new(key.clone(), Bsdf::Diffuse(Diffuse { reflectance: Texture::constant(0.5) })),
                    None,
                    None,
                ),
            },
        };
        let mut data = data.transform(&t);
        if m.face_normals {
            data.normals.clear();
        }
        let mut mesh = data.into_mesh(format!("{}:{}", m.file, key));
        mesh.material = desc.materials.len() as u32;
        mesh.alpha = alpha;
        mesh.emission = emission;
        desc.materials.push(material);
        desc.meshes.push(mesh);
    }
    Ok(())
}

/// An override whose name matches none of the file's materials is a typo: those faces would
/// silently keep the file's material or a grey default.
fn warn_unused_overrides(m: &MeshSection, names: &[String], desc: &mut SceneDescription) {
    let mut unused: Vec<&String> = m.materials.keys().filter(|k| *k != "*" && !names.contains(k)).collect();
    unused.sort();
    for key in unused {
        desc.warnings.push(format!(
            "mesh '{}': material override '{key}' matches none of the file's materials ({})",
            m.file,
            names.join(", ")
        ));
    }
}

/// A Mitsuba scene's shapes and materials, its materials overridden by BSDF id (the seeds'
/// Sponza configuration over the Mitsuba Sponza). Its sensor, film and lights other than
/// emissive shapes are not taken: this file supplies them.
fn load_mitsuba_shapes(
    ctx: &mut Ctx,
    m: &MeshSection,
    file: &Path,
    desc: &mut SceneDescription,
) -> Result<(), LoadError> {
    if m.transform.is_some() || m.face_normals {
        return Err(ctx.err(format!("mesh '{}': transform and face_normals apply to OBJ and PLY files", m.file)));
    }
    if !file.exists() {
        return Err(ctx.err(format!("mesh '{}': file not found", m.file)));
    }
    let root = file.parent().unwrap_or(Path::new(".")).to_path_buf();
    let sub = super::mitsuba::Loader::new(&root, &[]).load(file)?;
    let names: Vec<String> = sub.materials.iter().map(|x| x.name.clone()).collect();
    warn_unused_overrides(m, &names, desc);
    let offset = desc.materials.len() as u32;
    for material in sub.materials {
        let chosen = match m.materials.get(&material.name).or_else(|| m.materials.get("*")) {
            Some(o) => override_material(ctx, &material.name, o)?,
            None => material,
        };
        desc.materials.push(chosen);
    }
    for mut mesh in sub.meshes {
        if m.drop_emitters && mesh.emission.is_some() {
            continue;
        }
        mesh.material += offset;
        mesh.name = format!("{}:{}", m.file, mesh.name);
        desc.meshes.push(mesh);
    }
    desc.warnings.extend(sub.warnings.into_iter().filter(|w| !w.contains("no sensor")));
    Ok(())
}

fn add_light(ctx: &Ctx, l: &LightSection, desc: &mut SceneDescription) -> Result<(), LoadError> {
    let need = |v: Option<[f32; 3]>, what: &str| {
        v.map(|a| vec3(a[0], a[1], a[2])).ok_or_else(|| ctx.err(format!("{} light needs '{what}'", l.kind)))
    };
    let color = |c: Option<Color>, what: &str| {
        c.map(Color::rgb).ok_or_else(|| ctx.err(format!("{} light needs '{what}'", l.kind)))
    };
    let emissive_shape = |data: TriangleData, radiance: Rgb, desc: &mut SceneDescription, name: &str| {
        let mut mesh = data.into_mesh(name.into());
        mesh.material = desc.materials.len() as u32;
        mesh.emission = Some(radiance);
        desc.materials.push(Material::new(name, Bsdf::Black));
        desc.meshes.push(mesh);
    };
    match l.kind.as_str() {
        "disk" | "quad" => {
            let p = need(l.position, "position")?;
            let n = l
                .normal
                .and_then(unit)
                .ok_or_else(|| ctx.err(format!("{} light needs a non-zero 'normal'", l.kind)))?;
            let f = Frame::from_normal(n);
            let (sx, sy, data) = if l.kind == "disk" {
                let r = l.radius.filter(|r| *r > 0.0).ok_or_else(|| ctx.err("disk light needs a positive 'radius'"))?;
                (r, r, shapes::disk(256))
            } else {
                let [w, h] = l
                    .size
                    .filter(|s| s[0] > 0.0 && s[1] > 0.0)
                    .ok_or_else(|| ctx.err("quad light needs a positive 'size'"))?;
                (w * 0.5, h * 0.5, shapes::rectangle())
            };
            let m = [
                [(f.s.x * sx) as f64, (f.t.x * sy) as f64, f.n.x as f64, p.x as f64],
                [(f.s.y * sx) as f64, (f.t.y * sy) as f64, f.n.y as f64, p.y as f64],
                [(f.s.z * sx) as f64, (f.t.z * sy) as f64, f.n.z as f64, p.z as f64],
                [0.0, 0.0, 0.0, 1.0],
            ];
            let t = Transform::from_matrix(m).ok_or_else(|| ctx.err("degenerate light shape"))?;
            emissive_shape(data.transform(&t), color(l.radiance, "radiance")?, desc, &l.kind);
        }
        "sphere" => {
            let p = need(l.position, "position")?;
            let r =
                l.radius.filter(|r| *r > 0.0).ok_or_else(|| ctx.err("sphere light needs a positive 'radius'"))? as f64;
            let t = Transform::translate([p.x as f64, p.y as f64, p.z as f64])
                .compose(&Transform::scale([r, r, r]).expect("r > 0"));
            emissive_shape(shapes::sphere(64).transform(&t), color(l.radiance, "radiance")?, desc, "sphere");
        }
        "point" => desc.lights.push(Light::Point {
            position: need(l.position, "position")?,
            intensity: color(l.intensity, "intensity")?,
        }),
        "spot" => {
            let p = need(l.position, "position")?;
            let d = need(l.target, "target")? - p;
            let d = unit([d.x, d.y, d.z]).ok_or_else(|| ctx.err("spot light target equals its position"))?;
            let cutoff = l.cutoff_angle.unwrap_or(20.0).to_radians();
            let beam = l.beam_width.map(f32::to_radians).unwrap_or(cutoff * 0.75).min(cutoff);
            desc.lights.push(Light::Spot {
                position: p,
                frame: Frame::from_normal(d),
                intensity: color(l.intensity, "intensity")?,
                cos_cutoff: cutoff.cos(),
                cutoff,
                beam_width: beam,
            });
        }
        "directional" => {
            let d =
                l.direction.and_then(unit).ok_or_else(|| ctx.err("directional light needs a non-zero 'direction'"))?;
            desc.lights.push(Light::Directional { direction: d, irradiance: color(l.irradiance, "irradiance")? });
        }
        "constant" => desc.lights.push(Light::Constant { radiance: color(l.radiance, "radiance")? }),
        other => {
            return Err(ctx
                .err(format!("unknown light type '{other}' (disk, quad, sphere, point, spot, directional, constant)")))
        }
    }
    Ok(())
}
