//! The embedded default scene: two rooms joined by a door left ajar, the only light in the
//! far room. Everything seen from the camera room arrives through the gap, which is the
//! situation skelight's estimators exist for.

use super::shapes;
use super::{Mesh, RenderSettings, Scene, SceneDescription};
use crate::camera::{Camera, FovAxis, Lens};
use crate::color::{rgb, Rgb};
use crate::film::Filter;
use crate::material::{Bsdf, Diffuse, Material};
use crate::math::{vec3, Transform, Vec3};
use crate::texture::Texture;

/// Axis-aligned box from `min` to `max`, optionally rotated about the vertical through `pivot`.
fn block(min: Vec3, max: Vec3, material: u32, turn: Option<(Vec3, f64)>) -> Mesh {
    let c = (min + max) * 0.5;
    let h = (max - min) * 0.5;
    let mut t = Transform::translate([c.x as f64, c.y as f64, c.z as f64])
        .compose(&Transform::scale([h.x as f64, h.y as f64, h.z as f64]).expect("box has volume"));
    if let Some((p, deg)) = turn {
        let to = Transform::translate([p.x as f64, p.y as f64, p.z as f64]);
        let rot = Transform::rotate([0.0, 1.0, 0.0], deg).expect("valid axis");
        t = to.compose(&rot).compose(&to.inverse()).compose(&t);
    }
    let mut m = shapes::cube().transform(&t).into_mesh(format!("block{material}"));
    m.material = material;
    m
}

pub fn two_rooms_description() -> SceneDescription {
    let diffuse =
        |name: &str, c: Rgb| Material::new(name, Bsdf::Diffuse(Diffuse { reflectance: Texture::Constant(c) }));
    let materials = vec![
        diffuse("walls", Rgb::splat(0.72)),
        diffuse("floor", rgb(0.55, 0.38, 0.22)),
        diffuse("door", rgb(0.6, 0.12, 0.08)),
        diffuse("crate", rgb(0.25, 0.45, 0.6)),
        diffuse("lamp", Rgb::splat(0.0)),
    ];
    let (walls, floor, door, crate_, lamp) = (0, 1, 2, 3, 4);
    let (w, h, d, t) = (8.0f32, 2.5f32, 4.0f32, 0.1f32);
    let mut meshes = vec![
        block(vec3(-t, -t, -t), vec3(w + t, 0.0, d + t), floor, None),
        block(vec3(-t, h, -t), vec3(w + t, h + t, d + t), walls, None),
        block(vec3(-t, 0.0, -t), vec3(0.0, h, d + t), walls, None),
        block(vec3(w, 0.0, -t), vec3(w + t, h, d + t), walls, None),
        block(vec3(0.0, 0.0, -t), vec3(w, h, 0.0), walls, None),
        block(vec3(0.0, 0.0, d), vec3(w, h, d + t), walls, None),
        // Partition at x = 4 with a doorway z ∈ [1.5, 2.5], y < 2.
        block(vec3(4.0, 0.0, 0.0), vec3(4.0 + t, h, 1.5), walls, None),
        block(vec3(4.0, 0.0, 2.5), vec3(4.0 + t, h, d), walls, None),
        block(vec3(4.0, 2.0, 1.5), vec3(4.0 + t, h, 2.5), walls, None),
        // The door, hinged at z = 2.5 on the far side, open by 20 degrees into the far room.
        block(vec3(4.1, 0.01, 1.5), vec3(4.15, 1.99, 2.5), door, Some((vec3(4.15, 0.0, 2.5), -20.0))),
        // Something to cast shadows in each room.
        block(vec3(1.2, 0.0, 0.6), vec3(2.0, 0.8, 1.4), crate_, None),
        block(vec3(5.5, 0.0, 2.6), vec3(6.3, 1.1, 3.4), crate_, None),
    ];
    // Ceiling lamp in the far room, facing down.
    let lamp_t = Transform::translate([6.8, (h - 0.01) as f64, 1.2])
        .compose(&Transform::rotate([1.0, 0.0, 0.0], 90.0).expect("axis"))
        .compose(&Transform::scale([0.5, 0.5, 1.0]).expect("scale"));
    let mut light = shapes::rectangle().transform(&lamp_t).into_mesh("lamp".into());
    light.material = lamp;
    light.emission = Some(rgb(120.0, 108.0, 90.0));
    meshes.push(light);
    let settings = RenderSettings {
        width: 320,
        height: 240,
        filter: Filter::Box,
        spp: 16,
        max_depth: 8,
        rr_depth: 5,
        integrator: "path".into(),
        integrator_params: Vec::new(),
    };
    let view = Transform::look_at([0.5, 1.4, 3.6], [4.1, 1.0, 1.9], [0.0, 1.0, 0.0]).expect("valid view");
    let camera =
        Camera::new(view, settings.width, settings.height, 62.0, FovAxis::X, Lens::PINHOLE, Camera::DEFAULT_NEAR_CLIP);
    SceneDescription { meshes, materials, lights: Vec::new(), camera: Some(camera), settings, warnings: Vec::new() }
}

pub fn two_rooms() -> Scene {
    Scene::build(two_rooms_description()).expect("the embedded scene is valid")
}
