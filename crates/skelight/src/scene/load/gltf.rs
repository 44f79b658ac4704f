//! glTF 2.0 (.gltf and .glb): triangle meshes through the node hierarchy, metallic-roughness
//! materials mapped onto ours, base-colour and emissive textures, KHR_lights_punctual and
//! perspective cameras. Referenced files must stay inside the scene's folder.

use std::path::Path;
use std::sync::Arc;

use super::{confined_file, LoadError};
use crate::boundary::catch_panic;
use crate::camera::{Camera, FovAxis, Lens};
use crate::color::Rgb;
use crate::film::Filter;
use crate::imageio::Image;
use crate::light::Light;
use crate::material::microfacet::{Microfacet, MicrofacetType};
use crate::material::{Bsdf, Conductor, Diffuse, Material, RoughConductor, RoughPlastic};
use crate::math::{vec2, vec3, Frame, Transform, Vec3};
use crate::scene::shapes::TriangleData;
use crate::scene::{RenderSettings, SceneDescription};
use crate::texture::{Bitmap, TexFilter, Texture, UvTransform};

fn to_transform(m: [[f32; 4]; 4]) -> Option<Transform> {
    // glTF matrices are column-major: m[column][row].
    let mut r = [[0.0f64; 4]; 4];
    for (c, col) in m.iter().enumerate() {
        for (row, v) in col.iter().enumerate() {
            r[row][c] = *v as f64;
        }
    }
    Transform::from_matrix(r)
}

/// A decoded glTF image as a linear texture (`srgb`: decode base colours, not data maps).
fn texture_of(img: &gltf::image::Data, srgb: bool) -> Option<Texture> {
    use gltf::image::Format;
    let (w, h) = (img.width as usize, img.height as usize);
    let channels = match img.format {
        Format::R8 => 1,
        Format::R8G8 => 2,
        Format::R8G8B8 => 3,
        Format::R8G8B8A8 => 4,
        _ => return None,
    };
    if img.pixels.len() < w * h * channels {
        return None;
    }
    let pixels = (0..w * h)
        .map(|i| {
            let px = &img.pixels[i * channels..];
            let v = |k: usize| px[k.min(channels - 1).min(2)] as f32 / 255.0;
            if channels < 3 {
                Rgb::splat(v(0))
            } else {
                Rgb::from_array([v(0), v(1), v(2)])
            }
        })
        .collect();
    let bitmap = Bitmap::new(Image { width: w, height: h, pixels }, srgb, TexFilter::Bilinear);
    Some(Texture::Bitmap { bitmap: Arc::new(bitmap), to_uv: UvTransform::IDENTITY })
}

/// Our closest material to a metallic-roughness one: metals become (rough) conductors that
/// reflect the base colour, dielectrics a (rough) plastic with the base colour beneath.
fn material_of(m: &gltf::Material, images: &[gltf::image::Data], warnings: &mut Vec<String>) -> Material {
    let pbr = m.pbr_metallic_roughness();
    let factor = pbr.base_color_factor();
    let base_rgb = Rgb::from_array([factor[0], factor[1], factor[2]]);
    let base = match pbr.base_color_texture().and_then(|t| images.get(t.texture().source().index())) {
        Some(img) => match texture_of(img, true) {
            Some(Texture::Bitmap { bitmap, to_uv }) if base_rgb == Rgb::WHITE => Texture::Bitmap { bitmap, to_uv },
            Some(t) => Texture::Scale { scale: base_rgb.mean(), inner: Box::new(t) },
            None => Texture::Constant(base_rgb),
        },
        None => Texture::Constant(base_rgb),
    };
    if pbr.metallic_roughness_texture().is_some() {
        warnings
            .push(format!("material '{}': metallic-roughness texture ignored (factors used)", m.name().unwrap_or("")));
    }
    let roughness = pbr.roughness_factor().clamp(0.0, 1.0);
    let alpha = roughness * roughness;
    let name = m.name().unwrap_or("gltf").to_string();
    let bsdf = if pbr.metallic_factor() >= 0.5 {
        // An ideal-mirror Fresnel tinted by the base colour (glTF's F0 = base colour).
        let (eta, k) = (Rgb::BLACK, Rgb::WHITE);
        if alpha < 1e-3 {
            Bsdf::Conductor(Conductor { eta, k, specular_reflectance: base })
        } else {
            let distribution = Microfacet::new(MicrofacetType::Ggx, alpha, alpha);
            Bsdf::RoughConductor(RoughConductor { distribution, eta, k, specular_reflectance: base })
        }
    } else if roughness >= 0.99 {
        Bsdf::Diffuse(Diffuse { reflectance: base })
    } else {
        let distribution = Microfacet::new(MicrofacetType::Ggx, alpha.max(1e-3), alpha.max(1e-3));
        Bsdf::RoughPlastic(RoughPlastic::new(distribution, base, Texture::constant(1.0), 1.5, true))
    };
    let bsdf = if m.double_sided() { Bsdf::TwoSided(Box::new(bsdf.clone()), Box::new(bsdf)) } else { bsdf };
    Material::new(name, bsdf)
}

/// Refuses a binary glTF whose header claims more bytes than the file has, or fewer than
/// the header itself: the `gltf` crate allocates the claimed length less 12 before reading.
fn check_glb_length(path: &Path) -> Result<(), String> {
    use std::io::Read;
    let mut head = [0u8; 12];
    let mut file = std::fs::File::open(path).map_err(|e| e.to_string())?;
    let file_len = file.metadata().map_err(|e| e.to_string())?.len();
    if file.read_exact(&mut head).is_err() || &head[..4] != b"glTF" {
        return Ok(());
    }
    let claimed = u32::from_le_bytes([head[8], head[9], head[10], head[11]]) as u64;
    if !(12..=file_len).contains(&claimed) {
        return Err(format!("its GLB header claims {claimed} bytes, but the file has {file_len}"));
    }
    Ok(())
}

/// Refuses accessor types the `gltf` crate's readers do not handle (they would panic).
fn check_accessors(prim: &gltf::Primitive) -> Result<(), String> {
    use gltf::accessor::{DataType, Dimensions};
    use gltf::mesh::Semantic;
    let want = |semantic: &str, a: gltf::Accessor, types: &[DataType], dims: Dimensions| {
        if types.contains(&a.data_type()) && a.dimensions() == dims {
            Ok(())
        } else {
            Err(format!(
                "{semantic} accessor {} holds {:?} {:?}, expected {types:?} {dims:?}",
                a.index(),
                a.data_type(),
                a.dimensions()
            ))
        }
    };
    if let Some(a) = prim.indices() {
        want("index", a, &[DataType::U8, DataType::U16, DataType::U32], Dimensions::Scalar)?;
    }
    for (semantic, a) in prim.attributes() {
        match semantic {
            Semantic::Positions => want("position", a, &[DataType::F32], Dimensions::Vec3)?,
            Semantic::Normals => want("normal", a, &[DataType::F32], Dimensions::Vec3)?,
            Semantic::TexCoords(0) => want("uv", a, &[DataType::U8, DataType::U16, DataType::F32], Dimensions::Vec2)?,
            _ => {}
        }
    }
    Ok(())
}

/// A primitive's triangle data and indices (all vertices in order when it has none);
/// `None` without positions.
fn read_primitive(prim: &gltf::Primitive, buffers: &[gltf::buffer::Data]) -> Option<(TriangleData, Vec<u32>)> {
    let reader = prim.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
    let positions: Vec<Vec3> = reader.read_positions()?.map(|p| vec3(p[0], p[1], p[2])).collect();
    let mut data = TriangleData { positions, ..Default::default() };
    if let Some(n) = reader.read_normals() {
        data.normals = n.map(|n| vec3(n[0], n[1], n[2])).collect();
    }
    if let Some(t) = reader.read_tex_coords(0) {
        data.uvs = t.into_f32().map(|t| vec2(t[0], t[1])).collect();
    }
    let indices = match reader.read_indices() {
        Some(i) => i.into_u32().collect(),
        None => (0..data.positions.len() as u32).collect(),
    };
    Some((data, indices))
}

/// Reads a .gltf or .glb file. The `gltf` crate's accessors unwrap what its validation lets
/// through (an image with neither a URI nor a buffer view, say), so the whole reading runs
/// behind a panic boundary.
pub fn load_gltf(path: &Path) -> Result<SceneDescription, LoadError> {
    catch_panic("glTF data", || read_gltf(path)).unwrap_or_else(|e| Err(LoadError::at(path, 0, e)))
}

fn read_gltf(path: &Path) -> Result<SceneDescription, LoadError> {
    let err = |msg: String| LoadError::at(path, 0, msg);
    check_glb_length(path).map_err(&err)?;
    // Refuse external files outside the scene folder before anything is read.
    let doc = gltf::Gltf::open(path).map_err(|e| err(format!("cannot parse glTF: {e}")))?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let uris = doc
        .buffers()
        .filter_map(|b| match b.source() {
            gltf::buffer::Source::Uri(u) => Some(u.to_string()),
            _ => None,
        })
        .chain(doc.images().filter_map(|i| match i.source() {
            gltf::image::Source::Uri { uri, .. } => Some(uri.to_string()),
            _ => None,
        }));
    // The importer percent-decodes a URI before it opens it: check the decoded path, links
    // resolved (`%2e%2e/x` is `../x`).
    for uri in uris.filter(|u| !u.starts_with("data:")) {
        let decoded =
            percent_decode(&uri).ok_or_else(|| err(format!("URI '{uri}' is not valid percent-encoded UTF-8")))?;
        confined_file(dir, dir, &decoded).map_err(&err)?;
    }
    let (document, buffers, images) = gltf::import(path).map_err(|e| err(format!("cannot load glTF data: {e}")))?;
    let mut desc = SceneDescription {
        settings: RenderSettings { filter: Filter::Box, ..RenderSettings::default() },
        ..Default::default()
    };
    let materials: Vec<Material> = document.materials().map(|m| material_of(&m, &images, &mut desc.warnings)).collect();
    let emissive: Vec<Option<Rgb>> = document
        .materials()
        .map(|m| {
            let e = m.emissive_factor();
            let s = m.emissive_strength().unwrap_or(1.0);
            let rgb = Rgb::from_array(e) * s;
            (rgb.max_component() > 0.0).then_some(rgb)
        })
        .collect();
    desc.materials = materials;
    let default_material = desc.materials.len() as u32;
    desc.materials.push(Material::new("gltf-default", Bsdf::Diffuse(Diffuse { reflectance: Texture::constant(0.8) })));
    let scene = document
        .default_scene()
        .or_else(|| document.scenes().next())
        .ok_or_else(|| err("no scene in the file".into()))?;
    let mut stack: Vec<(gltf::Node, Transform)> = scene.nodes().map(|n| (n, Transform::IDENTITY)).collect();
    // glTF's node hierarchy is a forest: a node reached twice is a cycle or has two parents.
    let mut reached = vec![false; document.nodes().len()];
    while let Some((node, parent)) = stack.pop() {
        if std::mem::replace(&mut reached[node.index()], true) {
            return Err(err(format!(
                "node {} is reached twice in the node hierarchy (a cycle, or a node with two parents)",
                node.index()
            )));
        }
        let local = to_transform(node.transform().matrix())
            .ok_or_else(|| err(format!("node {} has a singular transform", node.index())))?;
        let world = parent.compose(&local);
        for child in node.children() {
            stack.push((child, world));
        }
        if let Some(mesh) = node.mesh() {
            for prim in mesh.primitives() {
                if prim.mode() != gltf::mesh::Mode::Triangles {
                    desc.warnings.push(format!(
                        "{}: mesh {}: non-triangle primitive skipped",
                        path.display(),
                        mesh.index()
                    ));
                    continue;
                }
                check_accessors(&prim).map_err(|e| err(format!("mesh {}: {e}", mesh.index())))?;
                let (mut data, indices) = read_primitive(&prim, &buffers)
                    .ok_or_else(|| err(format!("mesh {} has no positions", mesh.index())))?;
                let nv = data.positions.len() as u32;
                if let Some(bad) = indices.iter().find(|&&i| i >= nv) {
                    return Err(err(format!("mesh {}: index {bad} beyond its {nv} vertices", mesh.index())));
                }
                data.indices = indices.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
                let data = data.transform(&world);
                let mut m = data.into_mesh(format!("{}#{}", mesh.name().unwrap_or("mesh"), mesh.index()));
                let mi = prim.material().index();
                m.material = mi.map(|i| i as u32).unwrap_or(default_material);
                m.emission = mi.and_then(|i| emissive[i]);
                desc.meshes.push(m);
            }
        }
        if let Some(light) = node.light() {
            let color = Rgb::from_array(light.color()) * light.intensity();
            let position = world.point(Vec3::ZERO);
            // Lights shine along their local −z.
            let dir = world.vector(vec3(0.0, 0.0, -1.0)).normalize();
            use gltf::khr_lights_punctual::Kind;
            desc.lights.push(match light.kind() {
                Kind::Point => Light::Point { position, intensity: color },
                Kind::Directional => Light::Directional { direction: dir, irradiance: color },
                Kind::Spot { inner_cone_angle, outer_cone_angle } => Light::Spot {
                    position,
                    frame: Frame::from_normal(dir),
                    intensity: color,
                    cos_cutoff: outer_cone_angle.cos(),
                    cutoff: outer_cone_angle,
                    beam_width: inner_cone_angle.min(outer_cone_angle),
                },
            });
        }
        if let (Some(cam), None) = (node.camera(), desc.camera.as_ref()) {
            if let gltf::camera::Projection::Perspective(p) = cam.projection() {
                // glTF cameras look down −z with +x right; ours look down +z with +x left.
                let flip = Transform::scale([-1.0, 1.0, -1.0]).expect("non-singular");
                let s = &desc.settings;
                let (w, h) = match p.aspect_ratio() {
                    Some(a) if a > 0.0 => (((s.height as f32) * a).round().max(1.0) as usize, s.height),
                    _ => (s.width, s.height),
                };
                desc.settings.width = w;
                desc.camera = Some(Camera::new(
                    world.compose(&flip),
                    w,
                    h,
                    p.yfov().to_degrees(),
                    FovAxis::Y,
                    Lens::PINHOLE,
                    p.znear(),
                ));
            }
        }
    }
    if desc.lights.is_empty() && emissive.iter().all(|e| e.is_none()) {
        desc.warnings.push(format!("{}: no lights; lit by a uniform white sky so that it is visible", path.display()));
        desc.lights.push(Light::Constant { radiance: Rgb::WHITE });
    }
    Ok(desc)
}

/// A URI's percent-escapes decoded (RFC 3986), or None where an escape or the result is invalid.
fn percent_decode(uri: &str) -> Option<String> {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = std::str::from_utf8(bytes.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}
