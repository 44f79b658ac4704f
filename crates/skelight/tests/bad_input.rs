//! Malformed or hostile input must give a clear error that names the file (and the line,
//! where there is one) and says what is wrong — never a panic, never a silent wrong image.

mod common;

use std::path::{Path, PathBuf};

use skelight::estimators::by_name;
use skelight::integrator::{render, RenderOptions};
use skelight::scene::load::load;

struct Dir(PathBuf);

impl Dir {
    fn new(name: &str) -> Dir {
        let d = std::env::temp_dir().join(format!("skelight-bad-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        Dir(d)
    }
    fn file(&self, name: &str, contents: &[u8]) -> PathBuf {
        let p = self.0.join(name);
        if let Some(parent) = p.parent() {
            std::fs::create_dir_all(parent).unwrap();
        }
        std::fs::write(&p, contents).unwrap();
        p
    }
}

impl Drop for Dir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// A minimal valid scene around `body`.
fn scene(body: &str) -> String {
    format!(
        r#"<scene version="3.0.0">
  <sensor type="perspective"><float name="fov" value="40"/>
    <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film>
  </sensor>
{body}
</scene>"#
    )
}

fn load_err(path: &Path) -> String {
    match load(path, &[]) {
        Ok(_) => panic!("{} loaded without error", path.display()),
        Err(e) => e.to_string(),
    }
}

fn assert_mentions(msg: &str, parts: &[&str]) {
    for p in parts {
        assert!(msg.contains(p), "error message {msg:?} does not mention {p:?}");
    }
}

#[test]
fn malformed_xml_reports_file_and_line() {
    let d = Dir::new("xml");
    let p = d.file("broken.xml", b"<scene version=\"3.0.0\">\n  <shape type=\"cube\">\n  </shap>\n</scene>\n");
    let e = load_err(&p);
    assert_mentions(&e, &["broken.xml:3", "malformed XML"]);
    let p = d.file("notscene.xml", b"<foo/>");
    assert_mentions(&load_err(&p), &["notscene.xml", "<scene>"]);
}

#[test]
fn undefined_parameters_and_bad_values_are_named() {
    let d = Dir::new("params");
    let p = d.file("a.xml", scene(r#"<shape type="sphere"><float name="radius" value="$r"/></shape>"#).as_bytes());
    assert_mentions(&load_err(&p), &["a.xml:", "$r"]);
    // The same file works once the parameter is given.
    assert!(load(&p, &[("r".into(), "2".into())]).is_ok());
    let p = d.file("b.xml", scene(r#"<shape type="sphere"><float name="radius" value="big"/></shape>"#).as_bytes());
    assert_mentions(&load_err(&p), &["b.xml:", "radius", "not a number"]);
    let p = d.file(
        "c.xml",
        scene(r#"<shape type="cube"><transform name="to_world"><scale value="0"/></transform></shape>"#).as_bytes(),
    );
    assert_mentions(&load_err(&p), &["c.xml:", "singular"]);
}

#[test]
fn sunsky_parameters_out_of_range_are_named() {
    let d = Dir::new("sunsky");
    let p =
        d.file("t.xml", scene(r#"<emitter type="sunsky"><float name="turbidity" value="20"/></emitter>"#).as_bytes());
    assert_mentions(&load_err(&p), &["t.xml:", "turbidity", "[1, 10]"]);
    let p = d.file(
        "a.xml",
        scene(r#"<emitter type="sunsky"><rgb name="albedo" value="0.2, 1.4, 0.2"/></emitter>"#).as_bytes(),
    );
    assert_mentions(&load_err(&p), &["a.xml:", "albedo"]);
    let p = d.file(
        "both.xml",
        scene(r#"<emitter type="sunsky"><vector name="sun_direction" value="0, 0, 1"/><float name="hour" value="9"/></emitter>"#)
            .as_bytes(),
    );
    assert_mentions(&load_err(&p), &["both.xml:", "sun_direction", "hour"]);
    let p = d.file(
        "ap.xml",
        scene(r#"<emitter type="sunsky"><float name="sun_aperture" value="-1"/></emitter>"#).as_bytes(),
    );
    assert_mentions(&load_err(&p), &["ap.xml:", "sun_aperture"]);
}

#[test]
fn files_outside_the_scene_folder_are_refused() {
    let d = Dir::new("escape");
    d.file("outside.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    let p = d.file(
        "inner/scene.xml",
        scene(r#"<shape type="obj"><string name="filename" value="../outside.obj"/></shape>"#).as_bytes(),
    );
    assert_mentions(&load_err(&p), &["scene.xml:", "leaves the scene folder"]);
    let p = d.file("inner/inc.xml", scene(r#"<include filename="../other.xml"/>"#).as_bytes());
    assert_mentions(&load_err(&p), &["inc.xml:", "leaves the scene folder"]);
    let p = d.file(
        "inner/abs.xml",
        scene(r#"<shape type="obj"><string name="filename" value="/etc/passwd"/></shape>"#).as_bytes(),
    );
    assert_mentions(&load_err(&p), &["abs.xml:", "absolute"]);
}

#[test]
fn missing_files_are_named() {
    let d = Dir::new("missing");
    let p =
        d.file("s.xml", scene(r#"<shape type="obj"><string name="filename" value="nope.obj"/></shape>"#).as_bytes());
    assert_mentions(&load_err(&p), &["s.xml:", "nope.obj", "not found"]);
    let tex = r#"<shape type="rectangle"><bsdf type="diffuse"><texture name="reflectance" type="bitmap">
        <string name="filename" value="gone.png"/></texture></bsdf></shape>"#;
    let p = d.file("t.xml", scene(tex).as_bytes());
    assert_mentions(&load_err(&p), &["t.xml:", "gone.png"]);
    assert_mentions(&load_err(&d.0.join("absent.xml")), &["absent.xml", "not found"]);
}

#[test]
fn corrupt_texture_is_an_error_naming_it() {
    let d = Dir::new("tex");
    d.file("bad.png", b"\x89PNG\r\n\x1a\nthis is not really a png");
    let tex = r#"<shape type="rectangle"><bsdf type="diffuse"><texture name="reflectance" type="bitmap">
        <string name="filename" value="bad.png"/></texture></bsdf></shape>"#;
    let p = d.file("t.xml", scene(tex).as_bytes());
    assert_mentions(&load_err(&p), &["bad.png"]);
}

/// Loads a scene whose one shape of `kind` reads `contents` from file `m.<kind>`.
fn mesh_scene(d: &Dir, kind: &str, contents: &[u8]) -> String {
    d.file(&format!("m.{kind}"), contents);
    let body = format!(r#"<shape type="{kind}"><string name="filename" value="m.{kind}"/></shape>"#);
    load_err(&d.file("s.xml", scene(&body).as_bytes()))
}

fn obj_scene(d: &Dir, obj: &[u8]) -> String {
    mesh_scene(d, "obj", obj)
}

#[test]
fn broken_obj_files() {
    let d = Dir::new("obj");
    assert_mentions(
        &obj_scene(&d, b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n"),
        &["m.obj:4", "vertex index 7 out of range"],
    );
    assert_mentions(&obj_scene(&d, b"v 0 0\n"), &["m.obj:1", "expected 3 numbers"]);
    assert_mentions(&obj_scene(&d, b"v 0 0 x\n"), &["m.obj:1", "not a number"]);
    assert_mentions(&obj_scene(&d, b"v 0 0 0\nv 1 0 0\nf 1 2\n"), &["m.obj:3", "at least 3"]);
    assert_mentions(&obj_scene(&d, b"v 0 0 nan\n"), &["m.obj:1", "not finite"]);
    assert_mentions(
        &obj_scene(&d, b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/5 2 3\n"),
        &["m.obj:4", "texture coordinate index 5"],
    );
}

fn ply_scene(d: &Dir, ply: &[u8]) -> String {
    mesh_scene(d, "ply", ply)
}

#[test]
fn broken_ply_files() {
    let d = Dir::new("ply");
    let header = |fmt: &str, nv: usize, nf: usize| {
        format!("ply\nformat {fmt} 1.0\nelement vertex {nv}\nproperty float x\nproperty float y\nproperty float z\nelement face {nf}\nproperty list uchar int vertex_indices\nend_header\n")
    };
    // Truncated binary body.
    let mut b = header("binary_little_endian", 3, 1).into_bytes();
    b.extend_from_slice(&[0u8; 20]);
    assert_mentions(&ply_scene(&d, &b), &["m.ply", "truncated"]);
    // Face index beyond the vertices.
    let a = format!("{}0 0 0\n1 0 0\n0 1 0\n3 0 1 9\n", header("ascii", 3, 1));
    assert_mentions(&ply_scene(&d, a.as_bytes()), &["m.ply", "vertex 9"]);
    // Absurd counts are refused before allocating.
    let h = header("binary_little_endian", 4_000_000_000, 1);
    assert_mentions(&ply_scene(&d, h.as_bytes()), &["m.ply", "more than the file can hold"]);
    assert_mentions(&ply_scene(&d, b"not a ply"), &["m.ply", "PLY"]);
    // A valid ASCII file loads.
    let ok = format!("{}0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", header("ascii", 3, 1));
    d.file("ok.ply", ok.as_bytes());
    let p = d.file("ok.xml", scene(r#"<shape type="ply"><string name="filename" value="ok.ply"/></shape>"#).as_bytes());
    assert_eq!(load(&p, &[]).unwrap().triangle_count(), 1);
}

#[test]
fn broken_serialized_files() {
    let d = Dir::new("ser");
    let ser = |bytes: &[u8], index: i32| {
        d.file("m.serialized", bytes);
        let body = format!(
            r#"<shape type="serialized"><string name="filename" value="m.serialized"/><integer name="shape_index" value="{index}"/></shape>"#
        );
        let p = d.file("s.xml", scene(&body).as_bytes());
        load_err(&p)
    };
    assert_mentions(&ser(b"garbage!", 0), &["m.serialized", "magic"]);
    // Valid header, table claiming one shape at an offset past the end.
    let mut b = vec![0x1C, 0x04, 0x04, 0x00];
    b.extend_from_slice(&1000u64.to_le_bytes());
    b.extend_from_slice(&1u32.to_le_bytes());
    assert_mentions(&ser(&b, 0), &["m.serialized", "shape 0"]);
    assert_mentions(&ser(&b, 3), &["m.serialized", "out of range"]);
    assert_mentions(&ser(&b, -1), &["s.xml", "shape_index"]);
}

#[test]
fn absurd_resolutions_and_sample_counts() {
    let d = Dir::new("res");
    let film = |w: i64, h: i64| {
        format!(
            r#"<scene version="3.0.0"><sensor type="perspective"><film type="hdrfilm"><integer name="width" value="{w}"/><integer name="height" value="{h}"/></film></sensor></scene>"#
        )
    };
    assert_mentions(&load_err(&d.file("zero.xml", film(0, 10).as_bytes())), &["zero.xml:", "must be positive"]);
    assert_mentions(&load_err(&d.file("huge.xml", film(1_000_000, 1_000_000).as_bytes())), &["huge.xml:", "too large"]);
    let spp = r#"<scene version="3.0.0"><sensor type="perspective"><sampler type="independent"><integer name="sample_count" value="0"/></sampler></sensor></scene>"#;
    assert_mentions(&load_err(&d.file("spp.xml", spp.as_bytes())), &["spp.xml:", "sample_count"]);
    // The render loop refuses a zero sample count or no stopping rule at all.
    let scene = skelight::scene::builtin::two_rooms();
    let mut pt = by_name("pt").unwrap();
    for opts in [
        RenderOptions { spp: Some(0), ..Default::default() },
        RenderOptions { spp: None, time: None, ..Default::default() },
    ] {
        assert!(render(&scene, pt.as_mut(), &opts, None, |_, _| true).is_err());
    }
}

#[test]
fn unknown_plugins_warn_and_render_visibly() {
    let d = Dir::new("unknown");
    let body = r#"<shape type="rectangle"><bsdf type="hair"/></shape><emitter type="constant"/>"#;
    let s = load(&d.file("u.xml", scene(body).as_bytes()), &[]).unwrap();
    assert!(s.warnings.iter().any(|w| w.contains("hair") && w.contains("magenta")), "{:?}", s.warnings);
    let body = r#"<shape type="rectangle"><bsdf type="diffuse"><texture name="reflectance" type="vertexcolors"/></bsdf>
        <medium name="interior" type="homogeneous"/></shape>"#;
    let s = load(&d.file("t.xml", scene(body).as_bytes()), &[]).unwrap();
    for what in ["vertexcolors", "<medium>"] {
        assert!(s.warnings.iter().any(|w| w.contains("t.xml:") && w.contains(what)), "{what}: {:?}", s.warnings);
    }
    let body = r#"<shape type="rectangle"/><integrator2/>"#;
    let s = load(&d.file("v.xml", scene(body).as_bytes()), &[]).unwrap();
    assert!(s.warnings.iter().any(|w| w.contains("integrator2")), "{:?}", s.warnings);
}

/// A file nested thousands deep would overflow the stack (the XML parser recurses per level):
/// it is refused before parsing, whatever the elements are.
#[test]
fn deeply_nested_xml_is_refused() {
    let d = Dir::new("deep");
    let n = 12_500;
    for (name, open, close) in [
        ("bsdf", r#"<bsdf type="twosided">"#, "</bsdf>"),
        ("shape", r#"<shape type="cube">"#, "</shape>"),
        ("unknown", "<foo>", "</foo>"),
    ] {
        let body = format!("<shape type=\"rectangle\">\n{}{}</shape>", open.repeat(n), close.repeat(n));
        let p = d.file(&format!("{name}.xml"), scene(&body).as_bytes());
        assert_mentions(&load_err(&p), &[&format!("{name}.xml:6"), "nested more than 100 deep"]);
    }
}

#[test]
fn include_cycles_are_refused() {
    let d = Dir::new("include");
    let p = d.file("self.xml", scene(r#"<include filename="self.xml"/>"#).as_bytes());
    assert_mentions(&load_err(&p), &["self.xml:", "'self.xml' includes itself"]);
    // Through another file, and with a mesh that made each round slow (a hang before).
    d.file("m.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    let mesh = r#"<shape type="obj"><string name="filename" value="m.obj"/></shape>"#;
    d.file("b.xml", format!(r#"<scene version="3.0.0">{mesh}<include filename="a.xml"/></scene>"#).as_bytes());
    let p = d.file("a.xml", scene(&format!(r#"{mesh}<include filename="b.xml"/>"#)).as_bytes());
    assert_mentions(&load_err(&p), &["b.xml:", "'a.xml' includes itself"]);
    // A file included twice side by side is no cycle.
    let p = d.file("twice.xml", scene(r#"<include filename="m.xml"/><include filename="m.xml"/>"#).as_bytes());
    d.file("m.xml", format!(r#"<scene version="3.0.0">{mesh}</scene>"#).as_bytes());
    assert_eq!(load(&p, &[]).unwrap().triangle_count(), 2);
}

/// A `<ref>` names an object already read, so a chain ends and a cycle is an unknown id.
#[test]
fn ref_cycles_are_unknown_ids_and_chains_end() {
    let d = Dir::new("ref");
    let cycle = r#"<bsdf type="twosided" id="a"><ref id="b"/></bsdf><bsdf type="twosided" id="b"><ref id="a"/></bsdf>"#;
    assert_mentions(&load_err(&d.file("c.xml", scene(cycle).as_bytes())), &["c.xml:", "no bsdf with id 'b'"]);
    let own = r#"<bsdf type="twosided" id="a"><ref id="a"/></bsdf>"#;
    assert_mentions(&load_err(&d.file("o.xml", scene(own).as_bytes())), &["o.xml:", "no bsdf with id 'a'"]);
    let chain = |kind: &str, links: usize| {
        let mut c = r#"<bsdf type="diffuse" id="b0"/>"#.to_string();
        for i in 1..links {
            c += &format!(r#"<bsdf type="{kind}" id="b{i}"><ref id="b{}"/></bsdf>"#, i - 1);
        }
        c + &format!(r#"<shape type="rectangle"><ref id="b{}"/></shape>"#, links - 1)
    };
    assert!(load(&d.file("chain.xml", scene(&chain("coating", 200)).as_bytes()), &[]).is_ok());
    // Each two-sided link holds the previous one twice: 2^200 BSDFs before the limit.
    let p = d.file("doubling.xml", scene(&chain("twosided", 200)).as_bytes());
    assert_mentions(&load_err(&p), &["doubling.xml:", "made of more than 256 BSDFs"]);
}

/// Coordinates past 1e12 overflow the BVH's costs and the default view's distance in f32.
#[test]
fn huge_coordinates_are_refused() {
    let d = Dir::new("huge");
    let c01 = std::fs::read_to_string(common::shared_dir().join("conformance/scenes/c01_cbox_area.xml")).unwrap();
    assert!(c01.contains(r#"<scale value="0.3"/>"#));
    let p = d.file("c01.xml", c01.replace(r#"<scale value="0.3"/>"#, r#"<scale value="1e30"/>"#).as_bytes());
    assert_mentions(&load_err(&p), &["c01.xml", "too far to render"]);
    // Without a camera, the default view is not built from them either.
    let obj = d.file("far.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 1e30\nf 1 2 3\n");
    assert_mentions(&load_err(&obj), &["far.obj", "too far to render"]);
    let body = r#"<shape type="obj"><string name="filename" value="far.obj"/></shape>"#;
    let p = d.file("nocam.xml", format!(r#"<scene version="3.0.0">{body}</scene>"#).as_bytes());
    assert_mentions(&load_err(&p), &["nocam.xml", "too far to render"]);
    // Far but within range, the default view still frames it.
    let p = d.file("ok.obj", b"v 0 0 1e11\nv 1 0 1e11\nv 0 1 1e11\nf 1 2 3\n");
    assert!(load(&p, &[]).is_ok());
}

/// The buffer of [`triangle_gltf`]: three positions, then indices 0, 0, 0 of any type.
fn triangle_bin() -> Vec<u8> {
    let mut bin = Vec::new();
    for v in [0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
        bin.extend_from_slice(&v.to_le_bytes());
    }
    bin.extend_from_slice(&[0u8; 12]);
    bin
}

/// A one-triangle glTF around `nodes` and the index accessor's component type.
fn triangle_gltf(nodes: &str, index_type: u32) -> String {
    let bin = triangle_bin();
    format!(
        r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0]}}], "nodes": {nodes},
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1}}]}}],
  "buffers": [{{"byteLength": 48, "uri": "data:application/octet-stream;base64,{}"}}],
  "bufferViews": [{{"buffer": 0, "byteLength": 36}}, {{"buffer": 0, "byteOffset": 36, "byteLength": 12}}],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}},
    {{"bufferView": 1, "componentType": {index_type}, "count": 3, "type": "SCALAR"}}]}}"#,
        common::base64(&bin)
    )
}

#[test]
fn broken_gltf_files() {
    let d = Dir::new("gltf");
    let p = d.file("ok.gltf", triangle_gltf(r#"[{"mesh": 0}]"#, 5125).as_bytes());
    assert_eq!(load(&p, &[]).unwrap().triangle_count(), 1);
    let p = d.file("float.gltf", triangle_gltf(r#"[{"mesh": 0}]"#, 5126).as_bytes());
    assert_mentions(&load_err(&p), &["float.gltf", "index accessor 1 holds F32"]);
    let p = d.file("cycle.gltf", triangle_gltf(r#"[{"mesh": 0, "children": [0]}]"#, 5125).as_bytes());
    assert_mentions(&load_err(&p), &["cycle.gltf", "node 0 is reached twice"]);
    let p = d.file("loop.gltf", triangle_gltf(r#"[{"children": [1]}, {"mesh": 0, "children": [0]}]"#, 5125).as_bytes());
    assert_mentions(&load_err(&p), &["loop.gltf", "reached twice"]);
    // Found by the fuzzer: a GLB header claiming fewer bytes than itself (the gltf crate
    // then allocates 4 GB), and an image with neither a URI nor a buffer view passes the gltf
    // crate's validation, then its accessor unwraps.
    let no_source = triangle_gltf(r#"[{"mesh": 0}]"#, 5125).replacen('{', r#"{"images": [{"name": "x"}], "#, 1);
    let p = d.file("image.gltf", no_source.as_bytes());
    assert_mentions(&load_err(&p), &["image.gltf", "malformed glTF data"]);
    let mut glb = b"glTF\x02\0\0\0\x04\0\0\0".to_vec();
    glb.extend_from_slice(&[0; 64]);
    assert_mentions(&load_err(&d.file("short.glb", &glb)), &["short.glb", "GLB header claims 4 bytes"]);
}

/// Mitsuba 0.6 loads a top-level object without an id and registers the ids nested in it
/// (Bitterli's scenes put the named BSDF inside an unnamed bump map).
#[test]
fn ids_nested_in_unnamed_top_level_objects_are_found() {
    let d = Dir::new("unnamed");
    let body = r#"<bsdf type="bumpmap"><texture type="checkerboard"/>
        <bsdf type="roughplastic" id="Material"><rgb name="diffuseReflectance" value="0.2, 0.3, 0.4"/></bsdf></bsdf>
        <texture type="scale"><texture type="checkerboard" id="checks"/></texture>
        <shape type="rectangle"><ref id="Material"/></shape>
        <shape type="rectangle"><bsdf type="diffuse"><ref name="reflectance" id="checks"/></bsdf></shape>"#;
    let s = load(&d.file("u.xml", scene(body).as_bytes()), &[]).unwrap();
    let m = &s.materials[s.meshes[0].material as usize];
    assert_eq!(m.name, "Material");
    assert!(matches!(m.bsdf, skelight::material::Bsdf::RoughPlastic(_)), "{:?}", m.bsdf);
    assert!(s.warnings.iter().any(|w| w.contains("u.xml:") && w.contains("no id")), "{:?}", s.warnings);
}

/// A thin lens's aperture must be finite and at least 0, its focus distance finite and
/// positive (1e39 reads as an infinite f32, which would make every camera ray NaN): in both
/// scene formats (the XML parser refuses non-finite numbers itself).
#[test]
fn thin_lens_parameters_out_of_range_are_named() {
    let d = Dir::new("lens");
    let lens = |aperture: &str, focus: &str| {
        let sensor = format!(
            r#"<sensor type="thinlens"><float name="fov" value="40"/><float name="aperture_radius" value="{aperture}"/><float name="focus_distance" value="{focus}"/>
    <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film></sensor>"#
        );
        format!(r#"<scene version="3.0.0">{sensor}</scene>"#)
    };
    let p = d.file("inf.xml", lens("0.1", "1e39").as_bytes());
    assert_mentions(&load_err(&p), &["inf.xml", "focus_distance"]);
    let p = d.file("neg.xml", lens("-0.1", "2").as_bytes());
    assert_mentions(&load_err(&p), &["neg.xml", "aperture_radius"]);
    assert!(load(&d.file("ok.xml", lens("0.1", "2").as_bytes()), &[]).is_ok());
    let toml = |aperture: &str, focus: &str| {
        format!(
            "[film]\nwidth = 8\nheight = 8\n[camera]\norigin = [0.0, 0.0, 5.0]\ntarget = [0.0, 0.0, 0.0]\n\
             aperture_radius = {aperture}\nfocus_distance = {focus}\n"
        )
    };
    let p = d.file("zero.toml", toml("0.1", "0.0").as_bytes());
    assert_mentions(&load_err(&p), &["zero.toml", "focus_distance"]);
    let p = d.file("neg.toml", toml("-0.5", "2.0").as_bytes());
    assert_mentions(&load_err(&p), &["neg.toml", "aperture_radius"]);
    assert!(load(&d.file("ok.toml", toml("0.1", "2.0").as_bytes()), &[]).is_ok());
}

/// Issue 59, "a missing file called something else": with a scene path relative to the
/// working directory, a missing mesh or include was reported as leaving the scene folder.
#[test]
fn a_missing_file_of_a_relative_scene_path_is_reported_missing() {
    let d = Dir::new("relative-missing");
    d.file("m.xml", scene(r#"<shape type="obj"><string name="filename" value="missing.obj"/></shape>"#).as_bytes());
    d.file("i.xml", scene(r#"<include filename="missing.xml"/>"#).as_bytes());
    // nextest runs each test in its own process: the working directory is ours.
    std::env::set_current_dir(&d.0).unwrap();
    for (file, missing) in [("m.xml", "missing.obj"), ("i.xml", "missing.xml")] {
        let msg = load_err(Path::new(file));
        assert_mentions(&msg, &[file, missing, "not found"]);
        assert!(!msg.contains("leaves"), "{msg}");
    }
}

/// Issue 59, "files read outside the scene folder": a glTF URI escaping by percent-encoding
/// or through a link, an MTL map climbing out of its OBJ's folder, an include linked out.
#[test]
fn files_outside_the_scene_folder_are_refused_after_decoding_and_links() {
    let d = Dir::new("escape2");
    let gltf = triangle_gltf(r#"[{"mesh": 0}]"#, 5125);
    let start = gltf.find("data:").unwrap();
    let end = start + gltf[start..].find('"').unwrap();
    let with_uri = |uri: &str| format!("{}{uri}{}", &gltf[..start], &gltf[end..]);
    d.file("outside.bin", &[0u8; 48]);
    let p = d.file("in/pct.gltf", with_uri("%2e%2e/outside.bin").as_bytes());
    assert_mentions(&load_err(&p), &["pct.gltf", "leaves the scene folder"]);
    std::os::unix::fs::symlink(d.0.join("outside.bin"), d.0.join("in/link.bin")).unwrap();
    let p = d.file("in/link.gltf", with_uri("link.bin").as_bytes());
    assert_mentions(&load_err(&p), &["link.gltf", "leaves the scene folder"]);
    // Inside the folder, a percent-encoded name still loads.
    d.file("in/a b.bin", &triangle_bin());
    let p = d.file("in/space.gltf", with_uri("a%20b.bin").as_bytes());
    assert_eq!(load(&p, &[]).unwrap().triangle_count(), 1);

    d.file("tex.png", b"not read");
    d.file("in/m.mtl", b"newmtl m\nKd 0.5 0.5 0.5\nmap_Kd ../tex.png\n");
    let p = d.file("in/m.obj", b"mtllib m.mtl\nusemtl m\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    assert_mentions(&load_err(&p), &["m.obj", "texture '../tex.png'", "leaves the scene folder"]);
    d.file("in/abs.mtl", b"newmtl m\nmap_Kd /etc/hostname\n");
    let p = d.file("in/abs.obj", b"mtllib abs.mtl\nusemtl m\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    assert_mentions(&load_err(&p), &["absolute"]);

    d.file("other.xml", scene("").as_bytes());
    std::os::unix::fs::symlink(d.0.join("other.xml"), d.0.join("in/linked.xml")).unwrap();
    let p = d.file("in/inc.xml", scene(r#"<include filename="linked.xml"/>"#).as_bytes());
    assert_mentions(&load_err(&p), &["inc.xml:", "leaves the scene folder"]);
}

/// Issue 59, "endless inputs": a FIFO as the scene, an include or a mesh blocked the load
/// forever; a link to /dev/zero was read until memory ran out.
#[test]
fn fifos_and_devices_are_not_read_as_scene_files() {
    let d = Dir::new("fifo");
    let fifo = d.0.join("pipe.xml");
    assert!(std::process::Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    // A load that blocks on the FIFO fails the test instead of hanging the suite (seen
    // blocking before the fix).
    let load_err_in_time = |p: PathBuf| {
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || tx.send(load_err(&p)));
        rx.recv_timeout(std::time::Duration::from_secs(30)).expect("the load blocked on a FIFO")
    };
    assert_mentions(&load_err_in_time(fifo), &["pipe.xml", "not a regular file"]);
    let p = d.file("inc.xml", scene(r#"<include filename="pipe.xml"/>"#).as_bytes());
    assert_mentions(&load_err_in_time(p), &["inc.xml:", "pipe.xml", "not a regular file"]);
    std::os::unix::fs::symlink("/dev/zero", d.0.join("zero.obj")).unwrap();
    let p =
        d.file("zero.xml", scene(r#"<shape type="obj"><string name="filename" value="zero.obj"/></shape>"#).as_bytes());
    assert_mentions(&load_err(&p), &["zero.xml:", "zero.obj", "leaves the scene folder"]);
}

/// Issue 59, "a real file that fails": a `.serialized` shape with neither precision flag
/// (Mitsuba 0.5 wrote such files) is single precision, as Mitsuba reads it; both flags set is
/// an error.
#[test]
fn a_serialized_shape_without_precision_flags_is_single_precision() {
    use std::io::Write;
    let d = Dir::new("ser-flags");
    let file = |flags: u32| {
        let mut shape = flags.to_le_bytes().to_vec();
        shape.extend_from_slice(b"tri\0");
        shape.extend_from_slice(&3u64.to_le_bytes());
        shape.extend_from_slice(&1u64.to_le_bytes());
        for v in [0f32, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 3.0, 0.0] {
            shape.extend_from_slice(&v.to_le_bytes());
        }
        for i in [0u32, 1, 2] {
            shape.extend_from_slice(&i.to_le_bytes());
        }
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        z.write_all(&shape).unwrap();
        let mut bytes = vec![0x1C, 0x04, 0x04, 0x00];
        bytes.extend(z.finish().unwrap());
        bytes.extend_from_slice(&0u64.to_le_bytes());
        bytes.extend_from_slice(&1u32.to_le_bytes());
        d.file("m.serialized", &bytes);
        let body = r#"<shape type="serialized"><string name="filename" value="m.serialized"/></shape>"#;
        load(&d.file("s.xml", scene(body).as_bytes()), &[])
    };
    for flags in [0, 0x1000] {
        let s = file(flags).unwrap_or_else(|e| panic!("flags {flags:#x}: {e}"));
        assert_eq!(s.triangle_count(), 1);
        let b = s.bounds();
        assert!((b.max.x - 2.0).abs() < 1e-6 && (b.max.y - 3.0).abs() < 1e-6, "flags {flags:#x}: {b:?}");
    }
    assert_mentions(&file(0x3000).map(|_| ()).unwrap_err().to_string(), &["m.serialized", "both"]);
}
