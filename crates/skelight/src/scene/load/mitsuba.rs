//! Mitsuba scene files, versions 0.4 to 3.x: camelCase or snake_case names, `<default>` and
//! `$name` substitution, `<ref>`, `<include>` (confined to the scene folder), transform
//! chains, shapes, BSDFs, textures, emitters, sensor, film and integrator settings.
//! Unsupported plugins produce a warning and a visible fallback (magenta), never silence.

use std::cell::RefCell;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use roxmltree::{Document, Node};

mod bsdf;
mod depth;
mod emitter;
mod sensor;

use super::{confined_file, LoadError};
use crate::camera::FovAxis;
use crate::color::{rgb, srgb_to_linear, Rgb};
use crate::geometry::Sphere;
use crate::imageio::Image;
use crate::material::fresnel::named_ior;
use crate::material::*;
use crate::math::{vec3, Frame, Transform, Vec3};
use crate::scene::shapes::{self, TriangleData};
use crate::scene::{Mesh, SceneDescription};
use crate::texture::{Bitmap, TexFilter, Texture, UvTransform};
use depth::MAX_XML_DEPTH;

/// `fooBar` and `foo_bar` name the same parameter; so do `intIOR` and `int_ior`.
pub fn normalize_name(s: &str) -> String {
    let mut out = String::with_capacity(s.len() + 4);
    let chars: Vec<char> = s.chars().collect();
    for (i, &c) in chars.iter().enumerate() {
        if c.is_ascii_uppercase() && i > 0 && chars[i - 1].is_ascii_lowercase() {
            out.push('_');
        }
        out.push(c.to_ascii_lowercase());
    }
    out
}

/// A BSDF as a shape uses it: the material and the mesh-level opacity mask, if any.
#[derive(Clone)]
struct MaterialRef {
    index: u32,
    alpha: Option<Texture>,
}

#[derive(Clone)]
struct Parsed {
    bsdf: Bsdf,
    perturbation: Option<Perturbation>,
    alpha: Option<Texture>,
}

pub struct Loader {
    /// Folder that every referenced file must stay inside.
    root: PathBuf,
    defines: HashMap<String, String>,
    overrides: HashMap<String, String>,
    materials: HashMap<String, MaterialRef>,
    /// Textures by id; filled while textures are read, nested ones included.
    textures: RefCell<HashMap<String, Texture>>,
    /// Warnings from texture reading, which only borrows the loader.
    texture_warnings: RefCell<Vec<String>>,
    bitmaps: RefCell<HashMap<(PathBuf, bool, bool), Arc<Bitmap>>>,
    /// Shared default materials: [non-emitters, emitters].
    default_materials: [Option<u32>; 2],
    desc: SceneDescription,
    /// File being parsed (for error messages) and its text (for line numbers).
    file: PathBuf,
    fov: (f32, FovAxis),
    version_major: u32,
    /// The file being read and those including it, to refuse an `<include>` cycle.
    open_files: Vec<PathBuf>,
    /// Files included so far: a tree of includes may not grow without bound either.
    files_read: usize,
}

/// Most `<include>`s one scene may read, repeats included.
const MAX_INCLUDES: usize = 1000;

type R<T> = Result<T, LoadError>;

impl Loader {
    pub fn new(root: &Path, overrides: &[(String, String)]) -> Loader {
        Loader {
            root: root.to_path_buf(),
            defines: HashMap::new(),
            overrides: overrides.iter().cloned().collect(),
            materials: HashMap::new(),
            textures: Default::default(),
            texture_warnings: Default::default(),
            bitmaps: Default::default(),
            default_materials: [None; 2],
            desc: SceneDescription::default(),
            file: PathBuf::new(),
            fov: (45.0, FovAxis::X),
            version_major: 3,
            open_files: Vec::new(),
            files_read: 0,
        }
    }

    pub fn load(mut self, path: &Path) -> R<SceneDescription> {
        self.load_file(path, true)?;
        let texture_warnings = self.texture_warnings.take();
        self.desc.warnings.extend(texture_warnings);
        if self.desc.camera.is_none() {
            self.warn(format!("{}: no sensor; using a default camera looking at the scene", path.display()));
        }
        Ok(self.desc)
    }

    fn warn(&mut self, msg: String) {
        self.desc.warnings.push(msg);
    }

    /// A warning about element `n`, prefixed with its file and line.
    fn warn_at(&mut self, n: Node, msg: impl std::fmt::Display) {
        let pos = n.document().text_pos_at(n.range().start);
        let text = format!("{}:{}: {msg}", self.file.display(), pos.row);
        self.warn(text);
    }

    fn err(&self, doc_node: Node, msg: impl Into<String>) -> LoadError {
        let pos = doc_node.document().text_pos_at(doc_node.range().start);
        LoadError::at(&self.file, pos.row as usize, msg.into())
    }

    fn load_file(&mut self, path: &Path, top: bool) -> R<()> {
        let text = super::read_text(path)?;
        if let Some(line) = depth::too_deep_at(&text, MAX_XML_DEPTH) {
            return Err(LoadError::at(path, line, format!("elements are nested more than {MAX_XML_DEPTH} deep")));
        }
        let doc = Document::parse(&text).map_err(|e| {
            let p = e.pos();
            LoadError::at(path, p.row as usize, format!("malformed XML: {e}"))
        })?;
        let saved = std::mem::replace(&mut self.file, path.to_path_buf());
        let root = doc.root_element();
        if root.tag_name().name() != "scene" {
            return Err(
                self.err(root, format!("expected <scene> as the root element, found <{}>", root.tag_name().name()))
            );
        }
        if top {
            if let Some(v) = root.attribute("version") {
                self.version_major = v.split('.').next().and_then(|s| s.parse().ok()).unwrap_or(3);
            }
        }
        // Defaults first, wherever they appear: they parameterise everything else.
        for n in root.children().filter(|n| n.is_element() && n.tag_name().name() == "default") {
            let name = n.attribute("name").ok_or_else(|| self.err(n, "<default> needs a name"))?;
            let value = n.attribute("value").ok_or_else(|| self.err(n, "<default> needs a value"))?;
            self.defines.entry(name.to_string()).or_insert_with(|| value.to_string());
        }
        self.open_files.push(path.canonicalize().unwrap_or_else(|_| path.to_path_buf()));
        for n in root.children().filter(|n| n.is_element()) {
            self.scene_child(n)?;
        }
        self.open_files.pop();
        self.file = saved;
        Ok(())
    }

    fn scene_child(&mut self, n: Node) -> R<()> {
        match n.tag_name().name() {
            "default" => Ok(()),
            "include" => {
                let f = self.attr(n, "filename")?.ok_or_else(|| self.err(n, "<include> needs a filename"))?;
                let p = self.resolve(n, &f)?;
                if self.open_files.contains(&p.canonicalize().unwrap_or_else(|_| p.clone())) {
                    return Err(self.err(n, format!("'{f}' includes itself (an <include> cycle)")));
                }
                self.files_read += 1;
                if self.files_read > MAX_INCLUDES {
                    return Err(self.err(n, format!("more than {MAX_INCLUDES} <include>s in one scene")));
                }
                self.load_file(&p, false)
            }
            "integrator" => self.integrator(n),
            "sensor" | "camera" => self.sensor(n),
            "shape" => self.shape(n),
            // Mitsuba 0.x loads unnamed top-level objects: nothing can refer to them, but
            // the ids of the objects nested in them are registered.
            "bsdf" | "texture" => {
                if n.attribute("id").is_none() {
                    let kind = n.tag_name().name();
                    self.warn_at(
                        n,
                        format!("this top-level <{kind}> has no id, so only what is nested in it can be referenced"),
                    );
                }
                if n.tag_name().name() == "bsdf" {
                    self.material(n).map(|_| ())
                } else {
                    self.texture_node(n).map(|_| ())
                }
            }
            "emitter" => self.emitter(n),
            other => {
                self.warn_at(n, format!("<{other}> is not supported; ignored"));
                Ok(())
            }
        }
    }

    // ----- attribute and property access -------------------------------------------------

    /// Attribute value with `$name` substitution.
    fn attr(&self, n: Node, key: &str) -> R<Option<String>> {
        let Some(raw) = n.attribute(key) else {
            return Ok(None);
        };
        if !raw.contains('$') {
            return Ok(Some(raw.to_string()));
        }
        let mut out = String::new();
        let mut rest = raw;
        while let Some(i) = rest.find('$') {
            out.push_str(&rest[..i]);
            let tail = &rest[i + 1..];
            let end = tail.find(|c: char| !(c.is_alphanumeric() || c == '_')).unwrap_or(tail.len());
            let name = &tail[..end];
            let value = self.overrides.get(name).or_else(|| self.defines.get(name)).ok_or_else(|| {
                self.err(n, format!("undefined parameter ${name} (add <default name=\"{name}\" …/> or -D {name}=…)"))
            })?;
            out.push_str(value);
            rest = &tail[end..];
        }
        out.push_str(rest);
        Ok(Some(out))
    }

    /// The child element carrying parameter `name`.
    fn prop<'a, 'i>(&self, n: Node<'a, 'i>, name: &str) -> Option<Node<'a, 'i>> {
        let want = normalize_name(name);
        n.children()
            .find(|c| c.is_element() && c.attribute("name").map(normalize_name).as_deref() == Some(want.as_str()))
    }

    fn numbers(&self, n: Node, s: &str) -> R<Vec<f32>> {
        s.split(|c: char| c == ',' || c.is_whitespace())
            .filter(|t| !t.is_empty())
            .map(|t| t.parse::<f32>().map_err(|_| self.err(n, format!("'{t}' is not a number"))))
            .collect()
    }

    fn float(&self, n: Node, name: &str, default: f32) -> R<f32> {
        let Some(p) = self.prop(n, name) else {
            return Ok(default);
        };
        let v = self.attr(p, "value")?.ok_or_else(|| self.err(p, format!("'{name}' needs a value")))?;
        // Mitsuba accepts names of materials for indices of refraction.
        if let Some(ior) = named_ior(&v) {
            return Ok(ior);
        }
        let x: f32 = v.trim().parse().map_err(|_| self.err(p, format!("'{name}': '{v}' is not a number")))?;
        if !x.is_finite() {
            return Err(self.err(p, format!("'{name}' is not finite")));
        }
        Ok(x)
    }

    fn int(&self, n: Node, name: &str, default: i64) -> R<i64> {
        let Some(p) = self.prop(n, name) else {
            return Ok(default);
        };
        let v = self.attr(p, "value")?.ok_or_else(|| self.err(p, format!("'{name}' needs a value")))?;
        v.trim().parse().map_err(|_| self.err(p, format!("'{name}': '{v}' is not an integer")))
    }

    fn boolean(&self, n: Node, name: &str, default: bool) -> R<bool> {
        let Some(p) = self.prop(n, name) else {
            return Ok(default);
        };
        match self.attr(p, "value")?.as_deref().map(str::trim) {
            Some("true") | Some("1") => Ok(true),
            Some("false") | Some("0") => Ok(false),
            other => Err(self.err(p, format!("'{name}': {other:?} is not a boolean"))),
        }
    }

    fn string(&self, n: Node, name: &str) -> R<Option<String>> {
        match self.prop(n, name) {
            Some(p) => self.attr(p, "value"),
            None => Ok(None),
        }
    }

    /// A colour from <rgb>, <srgb>, <spectrum> or <float>.
    fn color_of(&self, p: Node) -> R<Rgb> {
        let tag = p.tag_name().name();
        let v = self.attr(p, "value")?.ok_or_else(|| self.err(p, "colour needs a value"))?;
        if tag == "spectrum" && v.contains(':') {
            // Sampled spectrum "λ:v, …": its mean is the grey it looks like.
            let vals: Vec<f32> =
                v.split(',').filter_map(|e| e.split(':').nth(1)).filter_map(|x| x.trim().parse().ok()).collect();
            if vals.is_empty() {
                return Err(self.err(p, "empty spectrum"));
            }
            return Ok(Rgb::splat(vals.iter().sum::<f32>() / vals.len() as f32));
        }
        let xs = self.numbers(p, &v)?;
        let c = match xs.as_slice() {
            [a] => Rgb::splat(*a),
            [r, g, b] => rgb(*r, *g, *b),
            _ => return Err(self.err(p, format!("expected 1 or 3 values, found {}", xs.len()))),
        };
        if !c.is_finite() {
            return Err(self.err(p, "colour is not finite"));
        }
        Ok(if tag == "srgb" { c.map(srgb_to_linear) } else { c })
    }

    fn color(&self, n: Node, name: &str, default: Rgb) -> R<Rgb> {
        match self.prop(n, name) {
            Some(p) if p.tag_name().name() == "texture" || p.tag_name().name() == "ref" => {
                Ok(self.texture(n, name, default)?.mean())
            }
            Some(p) => self.color_of(p),
            None => Ok(default),
        }
    }

    /// Three numbers from `value="a"` / `value="x, y, z"` or from `x`, `y`, `z` attributes
    /// (missing ones take `default`).
    fn triple(&self, p: Node, default: f64) -> R<[f64; 3]> {
        if let Some(v) = self.attr(p, "value")? {
            let xs = self.numbers(p, &v)?;
            return match xs.as_slice() {
                [a] => Ok([*a as f64; 3]),
                [x, y, z] => Ok([*x as f64, *y as f64, *z as f64]),
                _ => Err(self.err(p, "expected 1 or 3 values")),
            };
        }
        let c = |k: &str| -> R<f64> {
            Ok(self
                .attr(p, k)?
                .map(|s| s.trim().parse::<f64>())
                .transpose()
                .map_err(|_| self.err(p, format!("bad '{k}'")))?
                .unwrap_or(default))
        };
        Ok([c("x")?, c("y")?, c("z")?])
    }

    fn vector3(&self, p: Node) -> R<Vec3> {
        let [x, y, z] = self.triple(p, 0.0)?;
        Ok(vec3(x as f32, y as f32, z as f32))
    }

    fn point(&self, n: Node, name: &str, default: Vec3) -> R<Vec3> {
        match self.prop(n, name) {
            Some(p) => self.vector3(p),
            None => Ok(default),
        }
    }

    fn transform(&self, n: Node, name: &str) -> R<Transform> {
        let Some(t) = self.prop(n, name) else {
            return Ok(Transform::IDENTITY);
        };
        let mut acc = Transform::IDENTITY;
        for op in t.children().filter(|c| c.is_element()) {
            let xyz = |default: f64| self.triple(op, default);
            let vec_attr = |k: &str| -> R<Option<[f64; 3]>> {
                let Some(v) = self.attr(op, k)? else {
                    return Ok(None);
                };
                let xs = self.numbers(op, &v)?;
                if xs.len() != 3 {
                    return Err(self.err(op, format!("'{k}' needs 3 values")));
                }
                Ok(Some([xs[0] as f64, xs[1] as f64, xs[2] as f64]))
            };
            let singular = || self.err(op, "transform is singular or not finite");
            let step = match op.tag_name().name() {
                "translate" => Transform::translate(xyz(0.0)?),
                "scale" => Transform::scale(xyz(1.0)?).ok_or_else(singular)?,
                "rotate" => {
                    let axis = xyz(0.0)?;
                    let angle: f64 = self
                        .attr(op, "angle")?
                        .ok_or_else(|| self.err(op, "rotate needs an angle"))?
                        .trim()
                        .parse()
                        .map_err(|_| self.err(op, "bad angle"))?;
                    Transform::rotate(axis, angle).ok_or_else(|| self.err(op, "rotation axis is zero"))?
                }
                "matrix" => {
                    let v = self.attr(op, "value")?.ok_or_else(|| self.err(op, "matrix needs a value"))?;
                    let xs = self.numbers(op, &v)?;
                    let mut m = [[0.0f64; 4]; 4];
                    match xs.len() {
                        16 => (0..16).for_each(|i| m[i / 4][i % 4] = xs[i] as f64),
                        9 => {
                            (0..9).for_each(|i| m[i / 3][i % 3] = xs[i] as f64);
                            m[3][3] = 1.0;
                        }
                        k => return Err(self.err(op, format!("matrix needs 9 or 16 values, found {k}"))),
                    }
                    Transform::from_matrix(m).ok_or_else(singular)?
                }
                "lookat" | "lookAt" => {
                    let origin = vec_attr("origin")?.ok_or_else(|| self.err(op, "lookat needs an origin"))?;
                    let target = vec_attr("target")?.ok_or_else(|| self.err(op, "lookat needs a target"))?;
                    let up = match vec_attr("up")? {
                        Some(u) => u,
                        None => {
                            // Any vector not parallel to the view direction.
                            let d = [target[0] - origin[0], target[1] - origin[1], target[2] - origin[2]];
                            let f = Frame::from_normal(vec3(d[0] as f32, d[1] as f32, d[2] as f32).normalize());
                            [f.t.x as f64, f.t.y as f64, f.t.z as f64]
                        }
                    };
                    Transform::look_at(origin, target, up)
                        .ok_or_else(|| self.err(op, "lookat: origin equals target or up is parallel to the view"))?
                }
                other => return Err(self.err(op, format!("unknown transform operation <{other}>"))),
            };
            acc = step.compose(&acc);
        }
        if acc.m.iter().flatten().any(|v| !v.is_finite()) {
            return Err(self.err(t, "transform is not finite"));
        }
        Ok(acc)
    }

    /// File path relative to the current file, refusing paths that leave the scene folder.
    fn resolve(&self, n: Node, name: &str) -> R<PathBuf> {
        let base = self.file.parent().unwrap_or(Path::new("."));
        confined_file(&self.root, base, name).map_err(|e| self.err(n, e))
    }

    // ----- textures ---------------------------------------------------------------------

    /// Parameter `name` as a texture: a constant, a nested <texture>, or a <ref>.
    fn texture(&self, n: Node, name: &str, default: Rgb) -> R<Texture> {
        let Some(p) = self.prop(n, name) else {
            return Ok(Texture::Constant(default));
        };
        match p.tag_name().name() {
            "texture" => self.texture_node(p),
            "ref" => {
                let id = self.attr(p, "id")?.ok_or_else(|| self.err(p, "<ref> needs an id"))?;
                self.textures
                    .borrow()
                    .get(&id)
                    .cloned()
                    .ok_or_else(|| self.err(p, format!("no texture with id '{id}'")))
            }
            _ => Ok(Texture::Constant(self.color_of(p)?)),
        }
    }

    fn uv_transform(&self, n: Node) -> R<UvTransform> {
        if self.prop(n, "to_uv").is_some() {
            let t = self.transform(n, "to_uv")?;
            let m = t.m;
            return Ok(UvTransform {
                m: [m[0][0] as f32, m[0][1] as f32, m[0][3] as f32, m[1][0] as f32, m[1][1] as f32, m[1][3] as f32],
            });
        }
        let s = self.float(n, "uvscale", 1.0)?;
        Ok(UvTransform::scale_offset(
            self.float(n, "uscale", s)?,
            self.float(n, "vscale", s)?,
            self.float(n, "uoffset", 0.0)?,
            self.float(n, "voffset", 0.0)?,
        ))
    }

    /// A `<texture>` element; one with an `id` can then be referenced.
    fn texture_node(&self, t: Node) -> R<Texture> {
        let tex = self.texture_of_type(t)?;
        if let Some(id) = self.attr(t, "id")? {
            self.textures.borrow_mut().insert(id, tex.clone());
        }
        Ok(tex)
    }

    fn texture_of_type(&self, t: Node) -> R<Texture> {
        let ty = self.attr(t, "type")?.unwrap_or_default();
        match ty.as_str() {
            "bitmap" => {
                let f = self.string(t, "filename")?.ok_or_else(|| self.err(t, "bitmap needs a filename"))?;
                let path = self.resolve(t, &f)?;
                let raw = self.boolean(t, "raw", false)?;
                let nearest = matches!(self.string(t, "filter_type")?.as_deref(), Some("nearest"));
                let bitmap = self.bitmap(t, &path, raw, nearest)?;
                Ok(Texture::Bitmap { bitmap, to_uv: self.uv_transform(t)? })
            }
            "checkerboard" => Ok(Texture::Checkerboard {
                color0: self.color(t, "color0", Rgb::splat(0.4))?,
                color1: self.color(t, "color1", Rgb::splat(0.2))?,
                to_uv: self.uv_transform(t)?,
            }),
            "scale" => {
                let inner = t
                    .children()
                    .find(|c| c.is_element() && (c.tag_name().name() == "texture" || c.tag_name().name() == "ref"));
                let inner = match inner {
                    Some(c) if c.tag_name().name() == "texture" => self.texture_node(c)?,
                    Some(c) => {
                        let id = self.attr(c, "id")?.unwrap_or_default();
                        self.textures
                            .borrow()
                            .get(&id)
                            .cloned()
                            .ok_or_else(|| self.err(c, format!("no texture with id '{id}'")))?
                    }
                    None => return Err(self.err(t, "scale texture needs a nested texture")),
                };
                Ok(Texture::Scale { scale: self.float(t, "scale", 1.0)?, inner: Box::new(inner) })
            }
            other => {
                let pos = t.document().text_pos_at(t.range().start);
                self.texture_warnings.borrow_mut().push(format!(
                    "{}:{}: texture type '{other}' is not supported; rendered as magenta",
                    self.file.display(),
                    pos.row
                ));
                Ok(Texture::Constant(FALLBACK_MAGENTA))
            }
        }
    }

    fn bitmap(&self, n: Node, path: &Path, raw: bool, nearest: bool) -> R<Arc<Bitmap>> {
        let key = (path.to_path_buf(), raw, nearest);
        if let Some(b) = self.bitmaps.borrow().get(&key) {
            return Ok(b.clone());
        }
        let img = Image::load(path).map_err(|e| self.err(n, e.to_string()))?;
        let is_hdr = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr"));
        let filter = if nearest { TexFilter::Nearest } else { TexFilter::Bilinear };
        let b = Arc::new(Bitmap::new(img, !raw && !is_hdr, filter));
        self.bitmaps.borrow_mut().insert(key, b.clone());
        Ok(b)
    }

    // ----- shapes -----------------------------------------------------------------------

    fn shape(&mut self, n: Node) -> R<()> {
        let ty = self.attr(n, "type")?.unwrap_or_default();
        let to_world = self.transform(n, "to_world")?;
        let mut smooth_if_missing = false;
        // The object-to-local transform of a sphere, kept to make it exact (see `Sphere`).
        let mut sphere_local = None;
        let data: TriangleData = match ty.as_str() {
            "obj" => {
                let f = self.string(n, "filename")?.ok_or_else(|| self.err(n, "obj needs a filename"))?;
                let obj = super::obj::load_obj(&self.resolve(n, &f)?)?;
                smooth_if_missing = true;
                merge_groups(obj.groups.into_iter().map(|g| g.data).collect())
            }
            "ply" => {
                let f = self.string(n, "filename")?.ok_or_else(|| self.err(n, "ply needs a filename"))?;
                smooth_if_missing = true;
                super::ply::load_ply(&self.resolve(n, &f)?)?
            }
            "serialized" => {
                let f = self.string(n, "filename")?.ok_or_else(|| self.err(n, "serialized needs a filename"))?;
                let idx = self.int(n, "shape_index", 0)?;
                if idx < 0 {
                    return Err(self.err(n, "shape_index must not be negative"));
                }
                smooth_if_missing = true;
                super::serialized::load_serialized(&self.resolve(n, &f)?, idx as usize)?
            }
            "rectangle" => shapes::rectangle(),
            "cube" => shapes::cube(),
            "disk" => shapes::disk(256),
            "sphere" => {
                let c = self.point(n, "center", Vec3::ZERO)?;
                let r = self.float(n, "radius", 1.0)? as f64;
                let local = Transform::translate([c.x as f64, c.y as f64, c.z as f64]).compose(
                    &Transform::scale([r, r, r]).ok_or_else(|| self.err(n, "sphere radius must not be zero"))?,
                );
                sphere_local = Some(local);
                shapes::sphere(64).transform(&local)
            }
            "cylinder" => {
                let p0 = self.point(n, "p0", Vec3::ZERO)?;
                let p1 = self.point(n, "p1", vec3(0.0, 0.0, 1.0))?;
                let r = self.float(n, "radius", 1.0)?;
                let axis = p1 - p0;
                let len = axis.length();
                if !(len > 0.0) || !(r > 0.0) {
                    return Err(self.err(n, "cylinder needs p0 ≠ p1 and a positive radius"));
                }
                let f = Frame::from_normal(axis / len);
                let m = [
                    [(f.s.x * r) as f64, (f.t.x * r) as f64, (f.n.x * len) as f64, p0.x as f64],
                    [(f.s.y * r) as f64, (f.t.y * r) as f64, (f.n.y * len) as f64, p0.y as f64],
                    [(f.s.z * r) as f64, (f.t.z * r) as f64, (f.n.z * len) as f64, p0.z as f64],
                    [0.0, 0.0, 0.0, 1.0],
                ];
                shapes::cylinder(128)
                    .transform(&Transform::from_matrix(m).ok_or_else(|| self.err(n, "degenerate cylinder"))?)
            }
            other => {
                self.warn_at(n, format!("shape type '{other}' is not supported; skipped"));
                return Ok(());
            }
        };
        let mut data = data.transform(&to_world);
        if to_world.flips_handedness() {
            // Mirroring reverses the winding; keep geometric normals facing the same side.
            data.indices.iter_mut().for_each(|t| t.swap(1, 2));
        }
        let face_normals = self.boolean(n, "face_normals", false)?;
        if face_normals {
            data.normals.clear();
        } else if data.normals.is_empty() && smooth_if_missing {
            data.normals = smooth_normals(&data);
            // Smoothing across a crease (a wall meeting a wall at 90° in one mesh) bends the
            // shading far off the faces and changes the image a lot: say so.
            let bend = largest_normal_bend(&data);
            if bend > 60.0 {
                self.warn_at(
                    n,
                    format!(
                        "this {ty} has no normals; smoothed as Mitsuba does, they bend up to {bend:.0}° off its \
                         faces (sharp creases); add <boolean name=\"face_normals\" value=\"true\"/> for flat shading"
                    ),
                );
            }
        }
        let flip_normals = self.boolean(n, "flip_normals", false)?;
        if flip_normals {
            data.normals.iter_mut().for_each(|v| *v = -*v);
            data.indices.iter_mut().for_each(|t| t.swap(1, 2));
        }
        // Faceted on request, and an ellipsoid stays a mesh.
        let sphere = sphere_local
            .filter(|_| !face_normals)
            .and_then(|local| Sphere::from_transform(&to_world.compose(&local), flip_normals));
        // Material: a nested <bsdf>, a <ref>, or the default diffuse.
        let mut mref = None;
        for c in n.children().filter(|c| c.is_element()) {
            match c.tag_name().name() {
                "bsdf" => mref = Some(self.material(c)?),
                "ref" => {
                    let id = self.attr(c, "id")?.unwrap_or_default();
                    let m = self
                        .materials
                        .get(&id)
                        .cloned()
                        .ok_or_else(|| self.err(c, format!("no bsdf with id '{id}'")))?;
                    mref = Some(m);
                }
                "medium" | "subsurface" => {
                    let what = c.tag_name().name();
                    self.warn_at(c, format!("<{what}> is not supported; the shape is rendered without it"));
                }
                _ => {}
            }
        }
        let mut emission = None;
        if let Some(e) = n.children().find(|c| c.is_element() && c.tag_name().name() == "emitter") {
            let ety = self.attr(e, "type")?.unwrap_or_default();
            if ety != "area" {
                return Err(self.err(e, format!("an emitter inside a shape must be 'area', not '{ety}'")));
            }
            emission = Some(self.color(e, "radiance", Rgb::WHITE)?);
        }
        // Without a BSDF, Mitsuba makes emitters black and everything else 50 % grey.
        let mref = match mref {
            Some(m) => m,
            None => MaterialRef { index: self.default_material(emission.is_some()), alpha: None },
        };
        let name = self.attr(n, "id")?.unwrap_or_else(|| format!("{ty}#{}", self.desc.meshes.len()));
        let mut mesh: Mesh = data.into_mesh(name);
        mesh.material = mref.index;
        mesh.alpha = mref.alpha;
        mesh.emission = emission;
        mesh.sphere = sphere;
        self.desc.meshes.push(mesh);
        Ok(())
    }
}

fn merge_groups(groups: Vec<TriangleData>) -> TriangleData {
    let mut out = TriangleData::default();
    let any_normals = groups.iter().all(|g| !g.normals.is_empty()) && !groups.is_empty();
    let any_uvs = groups.iter().all(|g| !g.uvs.is_empty()) && !groups.is_empty();
    for g in groups {
        let base = out.positions.len() as u32;
        out.positions.extend(&g.positions);
        if any_normals {
            out.normals.extend(&g.normals);
        }
        if any_uvs {
            out.uvs.extend(&g.uvs);
        }
        out.indices.extend(g.indices.iter().map(|t| t.map(|i| i + base)));
    }
    out
}

/// The unit normal of triangle `t` by its winding; `None` if it has no area.
fn unit_face_normal(d: &TriangleData, t: &[u32; 3]) -> Option<Vec3> {
    let p = t.map(|i| d.positions[i as usize]);
    let face = (p[1] - p[0]).cross(p[2] - p[0]);
    (face.length_squared() > 0.0).then(|| face.normalize())
}

/// The largest angle (degrees) between a triangle and the shading normal at one of its
/// corners.
fn largest_normal_bend(d: &TriangleData) -> f32 {
    let mut least_cos = 1.0f32;
    for t in &d.indices {
        let Some(face) = unit_face_normal(d, t) else { continue };
        for &i in t {
            least_cos = least_cos.min(face.dot(d.normals[i as usize]));
        }
    }
    least_cos.clamp(-1.0, 1.0).acos().to_degrees()
}

/// Angle-weighted vertex normals (what Mitsuba computes for meshes given without normals).
pub fn smooth_normals(d: &TriangleData) -> Vec<Vec3> {
    let mut n = vec![Vec3::ZERO; d.positions.len()];
    for t in &d.indices {
        let Some(face) = unit_face_normal(d, t) else { continue };
        let p = t.map(|i| d.positions[i as usize]);
        for k in 0..3 {
            let e1 = p[(k + 1) % 3] - p[k];
            let e2 = p[(k + 2) % 3] - p[k];
            let denom = (e1.length() * e2.length()).max(1e-30);
            let angle = (e1.dot(e2) / denom).clamp(-1.0, 1.0).acos();
            n[t[k] as usize] += face * angle;
        }
    }
    n.iter().map(|v| if v.length_squared() > 0.0 { v.normalize() } else { vec3(0.0, 0.0, 1.0) }).collect()
}
