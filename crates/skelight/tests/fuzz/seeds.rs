//! Seed files for the fuzzer, small and valid, written here; plus the conformance scenes of
//! ../shared (their 800 kB sphere.obj replaced by a small mesh of the same name).

use skelight::color::Rgb;
use skelight::imageio::Image;

use super::common::{base64, shared_dir};

/// A small OBJ with every kind of face reference, groups and a material library.
pub fn obj_files() -> Vec<Vec<u8>> {
    [
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
        "mtllib m.mtl\no quad\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\n\
         usemtl red\nf 1/1/1 2/2/1 3/3/1 4/4/1\ng back\nusemtl tex\nf -1//1 -2//1 -3//1\n",
        "# comment\nv 0 0 0 1\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 0.5 1\ns 1\nf 1 2 5\nf 2 3 5\nf 3 4 5\nf 4 1 5\nf 4 3 2 1\n",
        "v 0 0 0\nv 2 0 0\nv 2 2 0\nv 1 1 0\nv 0 2 0\nvt 0.5 0.5\nf 1/1 2/1 3/1 4/1 5/1\nl 1 2\np 3\n",
    ]
    .iter()
    .map(|s| s.as_bytes().to_vec())
    .collect()
}

pub fn mtl_files() -> Vec<Vec<u8>> {
    [
        "newmtl red\nKd 0.8 0.1 0.1\nKs 0 0 0\nNs 10\nillum 2\n\nnewmtl tex\nKd 1 1 1\nmap_Kd checker.png\nd 0.5\n",
        "newmtl red\nKd 0.5 0.5 0.5\nKs 0.4 0.4 0.4\nNs 200\nmap_bump -bm 0.5 leaf.png\nmap_d leaf.png\n\
         newmtl tex\nKe 1 1 1\nNi 1.5\nTr 0.1\n",
    ]
    .iter()
    .map(|s| s.as_bytes().to_vec())
    .collect()
}

fn ply_header(format: &str, nv: usize, nf: usize, extra: &str) -> String {
    format!(
        "ply\nformat {format} 1.0\ncomment fuzz seed\nelement vertex {nv}\nproperty float x\nproperty float y\n\
         property float z\n{extra}element face {nf}\nproperty list uchar int vertex_indices\nend_header\n"
    )
}

pub fn ply_files() -> Vec<Vec<u8>> {
    let mut out =
        vec![format!("{}0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n", ply_header("ascii", 4, 1, "")).into_bytes()];
    let extra = "property float nx\nproperty float ny\nproperty float nz\nproperty float u\nproperty float v\n";
    for (format, big) in [("binary_little_endian", false), ("binary_big_endian", true)] {
        let mut b = ply_header(format, 3, 1, extra).into_bytes();
        let f = |b: &mut Vec<u8>, v: f32| b.extend_from_slice(&if big { v.to_be_bytes() } else { v.to_le_bytes() });
        for p in [
            [0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0],
            [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0],
        ] {
            p.iter().for_each(|&v| f(&mut b, v));
        }
        b.push(3);
        for i in [0i32, 1, 2] {
            b.extend_from_slice(&if big { i.to_be_bytes() } else { i.to_le_bytes() });
        }
        out.push(b);
    }
    out
}

/// Mitsuba's .serialized format: zlib-compressed shapes and a table of their offsets.
pub fn serialized_files() -> Vec<Vec<u8>> {
    use std::io::Write;
    let shape = |flags: u32, normals: bool, uvs: bool| {
        let mut raw = Vec::new();
        raw.extend_from_slice(&flags.to_le_bytes());
        raw.extend_from_slice(b"mesh\0");
        raw.extend_from_slice(&3u64.to_le_bytes());
        raw.extend_from_slice(&1u64.to_le_bytes());
        let reals: Vec<f32> = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]].concat();
        reals.iter().for_each(|v| raw.extend_from_slice(&v.to_le_bytes()));
        if normals {
            (0..3).for_each(|_| [0f32, 0.0, 1.0].iter().for_each(|v| raw.extend_from_slice(&v.to_le_bytes())));
        }
        if uvs {
            [0f32, 0.0, 1.0, 0.0, 0.0, 1.0].iter().for_each(|v| raw.extend_from_slice(&v.to_le_bytes()));
        }
        [0u32, 1, 2].iter().for_each(|i| raw.extend_from_slice(&i.to_le_bytes()));
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        z.write_all(&raw).unwrap();
        let mut out = vec![0x1C, 0x04, 0x04, 0x00];
        out.extend(z.finish().unwrap());
        out
    };
    let file = |shapes: &[Vec<u8>]| {
        let (mut out, mut offsets) = (Vec::new(), Vec::new());
        for s in shapes {
            offsets.push(out.len() as u64);
            out.extend_from_slice(s);
        }
        offsets.iter().for_each(|o| out.extend_from_slice(&o.to_le_bytes()));
        out.extend_from_slice(&(shapes.len() as u32).to_le_bytes());
        out
    };
    vec![file(&[shape(0x1000, false, false)]), file(&[shape(0x1003, true, true), shape(0x1001, true, false)])]
}

/// The skelight TOML format around the companion mesh and texture files.
pub fn toml_files() -> Vec<Vec<u8>> {
    [
        "[film]\nwidth = 16\nheight = 12\nspp = 4\nfilter = \"tent\"\n[integrator]\nmax_depth = 4\n\
         [camera]\norigin = [0, 0, 5]\ntarget = [0, 0, 0]\nup = [0, 1, 0]\nfov = 40\nfov_axis = \"y\"\n\
         [[mesh]]\nfile = \"m.obj\"\ntransform = { translate = [0, 0, 1], scale = [2, 2, 2], rotate = [0, 1, 0, 30] }\n\
         [mesh.materials.red]\ntype = \"phong\"\ncolor = [0.5, 0.2, 0.2]\nspecular = 0.3\nexponent = 20\n\
         [mesh.materials.tex]\ntype = \"diffuse\"\ntexture = \"checker.png\"\ntwo_sided = true\n\
         [[light]]\ntype = \"quad\"\nposition = [0, 2, 0]\nnormal = [0, -1, 0]\nsize = [1, 1]\nradiance = 10\n",
        "[[mesh]]\nfile = \"m.ply\"\nface_normals = true\n[mesh.materials.x]\ntype = \"glass\"\nior = 1.5\n\
         [[light]]\ntype = \"point\"\nposition = [1, 1, 1]\nintensity = [1, 2, 3]\n\
         [[light]]\ntype = \"spot\"\nposition = [0, 3, 0]\ntarget = [0, 0, 0]\nintensity = 3\ncutoff_angle = 30\nbeam_width = 20\n\
         [[light]]\ntype = \"sphere\"\nposition = [0, 0, 3]\nradius = 0.5\nradiance = 2\n\
         [[light]]\ntype = \"directional\"\ndirection = [0, -1, 0]\nirradiance = 1\n\
         [[light]]\ntype = \"disk\"\nposition = [0, 4, 0]\nnormal = [0, -1, 0]\nradius = 1\nradiance = 5\n\
         [[light]]\ntype = \"constant\"\nradiance = 0.1\n",
    ]
    .iter()
    .map(|s| s.as_bytes().to_vec())
    .collect()
}

const SCENE_HEAD: &str = r#"<scene version="3.0.0">
  <default name="r" value="0.5"/>
  <integrator type="path"><integer name="max_depth" value="5"/></integrator>
  <sensor type="thinlens"><float name="fov" value="40"/><float name="aperture_radius" value="0.01"/>
    <float name="focus_distance" value="4"/>
    <transform name="to_world"><lookat origin="0, 1, 4" target="0, 0, 0" up="0, 1, 0"/></transform>
    <sampler type="independent"><integer name="sample_count" value="4"/></sampler>
    <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="12"/>
      <rfilter type="gaussian"><float name="stddev" value="0.5"/></rfilter></film>
  </sensor>
"#;

/// Mitsuba scenes using every plugin we read, each kind of file and `<include>`.
pub fn xml_files() -> Vec<Vec<u8>> {
    let bodies = [
        r#"<bsdf type="twosided" id="w"><bsdf type="roughplastic"><string name="distribution" value="ggx"/>
    <float name="alpha" value="$r"/><texture name="diffuse_reflectance" type="bitmap"><string name="filename" value="checker.png"/>
    <float name="uscale" value="2"/></texture></bsdf></bsdf>
  <texture type="checkerboard" id="ch"><rgb name="color0" value="0.1"/><rgb name="color1" value="0.9, 0.2, 0.1"/></texture>
  <shape type="obj"><string name="filename" value="m.obj"/><ref id="w"/>
    <transform name="to_world"><scale value="0.5"/><rotate y="1" angle="30"/><translate x="1"/></transform></shape>
  <shape type="ply"><string name="filename" value="m.ply"/><bsdf type="diffuse"><ref name="reflectance" id="ch"/></bsdf></shape>
  <shape type="serialized"><string name="filename" value="m.serialized"/><integer name="shape_index" value="0"/>
    <boolean name="face_normals" value="true"/></shape>
  <shape type="rectangle"><emitter type="area"><rgb name="radiance" value="5"/></emitter>
    <transform name="to_world"><matrix value="1 0 0 0 0 1 0 2 0 0 1 0 0 0 0 1"/></transform></shape>
  <emitter type="envmap"><string name="filename" value="sky.exr"/><float name="scale" value="0.5"/></emitter>"#,
        r#"<bsdf type="bumpmap"><texture type="bitmap"><string name="filename" value="leaf.png"/></texture>
    <float name="scale" value="0.1"/><bsdf type="roughconductor" id="metal"><string name="material" value="Au"/>
    <float name="alpha_u" value="0.1"/><float name="alpha_v" value="0.3"/></bsdf></bsdf>
  <shape type="sphere"><point name="center" x="0" y="0" z="0"/><float name="radius" value="0.5"/><ref id="metal"/></shape>
  <shape type="cylinder"><point name="p0" value="0, 0, 0"/><point name="p1" value="0, 1, 0"/><float name="radius" value="0.2"/>
    <bsdf type="mask"><texture name="opacity" type="bitmap"><string name="filename" value="leaf.png"/></texture>
    <bsdf type="dielectric"><float name="int_ior" value="1.5"/></bsdf></bsdf></shape>
  <shape type="disk"><bsdf type="coating"><bsdf type="conductor"/></bsdf><boolean name="flip_normals" value="true"/></shape>
  <shape type="cube"><bsdf type="ward"><string name="variant" value="ward-duer"/><float name="alphaU" value="0.2"/>
    <float name="alphaV" value="0.1"/></bsdf></shape>
  <emitter type="spot"><transform name="to_world"><lookat origin="0, 3, 0" target="0, 0, 0"/></transform>
    <float name="cutoff_angle" value="30"/></emitter>
  <emitter type="sunsky"><vector name="sun_direction" value="0, 1, 1"/><float name="turbidity" value="3"/></emitter>"#,
        r#"<include filename="inc.xml"/>
  <shape type="rectangle"><bsdf type="normalmap"><texture type="bitmap"><string name="filename" value="checker.png"/>
    <boolean name="raw" value="true"/></texture><bsdf type="phong"/></bsdf></shape>
  <shape type="rectangle"><bsdf type="roughdielectric"><float name="alpha" value="0.2"/></bsdf></shape>
  <shape type="rectangle"><bsdf type="thindielectric"/></shape>
  <shape type="rectangle"><bsdf type="plastic"><srgb name="diffuse_reflectance" value="0.3, 0.4, 0.5"/></bsdf></shape>
  <shape type="rectangle"><bsdf type="null"/></shape>
  <shape type="rectangle"><bsdf type="roughdiffuse"/></shape>
  <emitter type="point"><point name="position" value="0, 2, 0"/><spectrum name="intensity" value="400:1, 500:2"/></emitter>
  <emitter type="directional"><vector name="direction" value="0, -1, 0"/></emitter>
  <emitter type="constant"><rgb name="radiance" value="0.1"/></emitter>"#,
    ];
    let mut out: Vec<Vec<u8>> = bodies.iter().map(|b| format!("{SCENE_HEAD}  {b}\n</scene>\n").into_bytes()).collect();
    out.push(
        br#"<scene version="0.5.0"><emitter type="sun"><vector name="sunDirection" x="0" y="1" z="1"/></emitter>
  <shape type="rectangle"><bsdf type="roughcoating"><bsdf type="diffuse"/></bsdf></shape></scene>"#
            .to_vec(),
    );
    let dir = shared_dir().join("conformance/scenes");
    let mut names: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().path()).collect();
    names.sort();
    out.extend(names.iter().filter(|p| p.extension().is_some_and(|e| e == "xml")).map(|p| std::fs::read(p).unwrap()));
    out
}

/// A one-triangle glTF with normals, uvs, an embedded PNG texture, a node tree, a camera
/// and a light; and the same as a binary .glb.
pub fn gltf_parts() -> (String, Vec<u8>) {
    let mut bin = Vec::new();
    let floats: [f32; 24] = [
        0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0,
        0.0, 1.0,
    ];
    floats.iter().for_each(|v| bin.extend_from_slice(&v.to_le_bytes()));
    [0u16, 1, 2, 0].iter().for_each(|i| bin.extend_from_slice(&i.to_le_bytes()));
    let png = png_files().remove(0);
    let json = |buffer: &str| {
        format!(
            r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0, 2]}}],
  "extensionsUsed": ["KHR_lights_punctual"],
  "extensions": {{"KHR_lights_punctual": {{"lights": [{{"type": "spot", "intensity": 5, "spot": {{"outerConeAngle": 0.5}}}}]}}}},
  "nodes": [{{"children": [1], "translation": [0, 0, -3]}}, {{"mesh": 0, "scale": [2, 2, 2], "rotation": [0, 0.38, 0, 0.92]}},
    {{"camera": 0, "matrix": [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,2,1], "extensions": {{"KHR_lights_punctual": {{"light": 0}}}}}}],
  "cameras": [{{"type": "perspective", "perspective": {{"yfov": 0.8, "znear": 0.01, "aspectRatio": 1.5}}}}],
  "materials": [{{"pbrMetallicRoughness": {{"baseColorTexture": {{"index": 0}}, "metallicFactor": 0, "roughnessFactor": 0.5}},
    "emissiveFactor": [0.1, 0, 0], "doubleSided": true}}],
  "textures": [{{"source": 0}}],
  "images": [{{"uri": "data:image/png;base64,{}"}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}}, "indices": 3, "material": 0}}]}}],
  "buffers": [{{"byteLength": {}{buffer}}}],
  "bufferViews": [{{"buffer": 0, "byteLength": 36}}, {{"buffer": 0, "byteOffset": 36, "byteLength": 36}},
    {{"buffer": 0, "byteOffset": 72, "byteLength": 24}}, {{"buffer": 0, "byteOffset": 96, "byteLength": 6}}],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}},
    {{"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC3"}},
    {{"bufferView": 2, "componentType": 5126, "count": 3, "type": "VEC2"}},
    {{"bufferView": 3, "componentType": 5123, "count": 3, "type": "SCALAR"}}]}}"#,
            base64(&png),
            bin.len()
        )
    };
    let text = json(&format!(r#", "uri": "data:application/octet-stream;base64,{}""#, base64(&bin)));
    // GLB: header, JSON chunk (space-padded), BIN chunk (zero-padded).
    let mut j = json("").into_bytes();
    while j.len() % 4 != 0 {
        j.push(b' ');
    }
    let mut b = bin.clone();
    while b.len() % 4 != 0 {
        b.push(0);
    }
    let mut glb = Vec::new();
    glb.extend_from_slice(b"glTF");
    glb.extend_from_slice(&2u32.to_le_bytes());
    glb.extend_from_slice(&((12 + 8 + j.len() + 8 + b.len()) as u32).to_le_bytes());
    glb.extend_from_slice(&(j.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"JSON");
    glb.extend(j);
    glb.extend_from_slice(&(b.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"BIN\0");
    glb.extend(b);
    (text, glb)
}

fn gradient(w: usize, h: usize, scale: f32) -> Image {
    let mut img = Image::new(w, h);
    for (i, p) in img.pixels.iter_mut().enumerate() {
        *p = Rgb::from_array([(i % w) as f32 / w as f32, (i / w) as f32 / h as f32, 0.5]) * scale;
    }
    img
}

pub fn png_files() -> Vec<Vec<u8>> {
    let mut out = vec![gradient(4, 3, 1.0).to_png_bytes(0.0).unwrap(), gradient(1, 1, 1.0).to_png_bytes(0.0).unwrap()];
    let dir = shared_dir().join("conformance/scenes");
    out.extend(["checker.png", "leaf.png"].iter().map(|n| std::fs::read(dir.join(n)).unwrap()));
    out
}

pub fn jpeg_files() -> Vec<Vec<u8>> {
    [(8, 8, 90), (17, 5, 50)]
        .iter()
        .map(|&(w, h, q)| {
            let img = gradient(w, h, 255.0);
            let bytes: Vec<u8> = img.pixels.iter().flat_map(|p| p.to_array().map(|v| v as u8)).collect();
            let mut out = Vec::new();
            image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, q)
                .encode(&bytes, w as u32, h as u32, image::ExtendedColorType::Rgb8)
                .unwrap();
            out
        })
        .collect()
}

/// EXRs as skelight writes them (with a sample count) and the conformance sky.
pub fn exr_files(dir: &std::path::Path) -> Vec<Vec<u8>> {
    let mut out = Vec::new();
    for (i, (w, h)) in [(4, 3), (1, 1), (33, 2)].iter().enumerate() {
        let p = dir.join(format!("seed{i}.exr"));
        gradient(*w, *h, 3.0).save_exr_with(&p, &[("skelight.spp", 16.0)]).unwrap();
        out.push(std::fs::read(&p).unwrap());
    }
    out.push(std::fs::read(shared_dir().join("conformance/scenes/sky.exr")).unwrap());
    out
}
