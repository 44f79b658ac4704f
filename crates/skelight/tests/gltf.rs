//! glTF 2.0 loading, through a file written here: geometry, material, KHR point light and
//! camera must combine into an image with a known value.

mod common;

use common::*;
use skelight::estimators::by_name;
use skelight::scene::load::load;

/// A 20×20 floor quad at y = 0 (base colour 0.5, fully rough), a point light of intensity
/// 4π at height 2 above its centre, and a camera at height 1 looking straight down.
fn floor_gltf(buffer_uri: Option<&str>) -> String {
    let mut bin = Vec::new();
    for p in [[-10.0f32, 0.0, -10.0], [10.0, 0.0, -10.0], [10.0, 0.0, 10.0], [-10.0, 0.0, 10.0]] {
        p.iter().for_each(|v| bin.extend_from_slice(&v.to_le_bytes()));
    }
    for i in [0u16, 2, 1, 0, 3, 2] {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    let uri = buffer_uri
        .map(str::to_string)
        .unwrap_or_else(|| format!("data:application/octet-stream;base64,{}", base64(&bin)));
    let s = std::f32::consts::FRAC_1_SQRT_2;
    format!(
        r#"{{
  "asset": {{"version": "2.0"}},
  "extensionsUsed": ["KHR_lights_punctual"],
  "extensions": {{"KHR_lights_punctual": {{"lights": [{{"type": "point", "color": [1, 1, 1], "intensity": {intensity}}}]}}}},
  "scene": 0,
  "scenes": [{{"nodes": [0, 1, 2]}}],
  "nodes": [
    {{"mesh": 0}},
    {{"translation": [0, 2, 0], "extensions": {{"KHR_lights_punctual": {{"light": 0}}}}}},
    {{"camera": 0, "translation": [0, 1, 0], "rotation": [-{s}, 0, 0, {s}]}}
  ],
  "cameras": [{{"type": "perspective", "perspective": {{"yfov": 0.02, "znear": 0.01, "aspectRatio": 1.0}}}}],
  "materials": [{{"pbrMetallicRoughness": {{"baseColorFactor": [0.5, 0.5, 0.5, 1], "metallicFactor": 0, "roughnessFactor": 1}}}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1, "material": 0}}]}}],
  "buffers": [{{"byteLength": {len}, "uri": "{uri}"}}],
  "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": 48}}, {{"buffer": 0, "byteOffset": 48, "byteLength": 12}}],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-10, 0, -10], "max": [10, 0, 10]}},
    {{"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}}
  ]
}}"#,
        intensity = 4.0 * std::f32::consts::PI,
        len = bin.len(),
    )
}

fn write(name: &str, text: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("skelight-gltf-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// Radiance of the floor right below the light: ρ/π · I/h² = 0.5/π · 4π/4 = 0.5.
#[test]
fn floor_under_a_point_light_has_the_exact_radiance() {
    let mut scene = load(&write("floor.gltf", &floor_gltf(None)), &[]).unwrap();
    assert_eq!(scene.triangle_count(), 2);
    assert_eq!(scene.lights.len(), 1);
    scene.set_resolution(8, 8);
    let film = render_spp(&scene, by_name("pt").unwrap().as_mut(), 16, 1);
    let (m, se) = film_mean_se(&film);
    // L ∝ cos³θ off the axis; at the field's corners (θ ≤ 0.0142 rad) that loses 1.5·θ² < 3e-4.
    for c in 0..3 {
        assert!((m[c] - 0.5).abs() < 3e-4 + 5.0 * se[c], "floor radiance {m:?} ± {se:?}, expected 0.5");
    }
}

#[test]
fn buffers_outside_the_scene_folder_are_refused() {
    let e = load(&write("escape.gltf", &floor_gltf(Some("../secret.bin"))), &[]).err().expect("must fail").to_string();
    assert!(e.contains("escape.gltf") && e.contains("leaves the scene folder"), "{e}");
    let e = load(&write("broken.gltf", "{ not json"), &[]).err().expect("must fail").to_string();
    assert!(e.contains("broken.gltf") && e.contains("glTF"), "{e}");
}
