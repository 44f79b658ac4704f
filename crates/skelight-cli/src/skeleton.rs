//! `skelight skeleton`: the empty-space analysis of a scene, written as files a person or a
//! program can read — the skeleton and the filtered skeleton (JSON and PLY line sets), the
//! opening portals (JSON) and the per-stage timings.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result};
use skelight::scene::Scene;
use skelight_shape::pipeline::{analyse, Analysis, AnalysisSettings, Anchor, ANCHOR_REACH};
use skelight_shape::reach::Kept;
use skelight_shape::skeleton::SkeletonGraph;

/// Runs the analysis of `scene` with `settings` and writes its outputs into `dir`, with
/// warnings for anchors it could not place and for scenes that enclose nothing.
pub fn run(scene: &Scene, settings: &AnalysisSettings, dir: &Path, quiet: bool) -> Result<Analysis> {
    let a = analyse(&scene_triangles(scene), settings).context("empty-space analysis")?;
    for (anchor, voxel) in settings.anchors.iter().zip(&a.anchor_voxels) {
        if voxel.is_none() {
            eprintln!(
                "warning: no empty voxel within {ANCHOR_REACH} voxels of the anchor at {:?} on its side: the skeleton is not pulled there",
                anchor.position
            );
        }
    }
    if a.reach.kept == Kept::AllSourceUnplaced {
        for (source, voxel) in settings.sources.iter().zip(&a.source_voxels) {
            if voxel.is_none() {
                eprintln!(
                    "warning: the camera or light at {:?} has no empty voxel within {ANCHOR_REACH} voxels on its side (inside a solid or outside the grid): every empty component is kept, as with --keep-all-space",
                    source.position
                );
            }
        }
    }
    if a.enclosed == 0.0 {
        eprintln!(
            "warning: the empty space analysed encloses nothing at this resolution (every voxel of it reaches the grid's border): the skeleton runs through the air around the scene too"
        );
    }
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let write = |name: &str, text: &str| crate::write_text(&dir.join(name), text);
    write("skeleton.json", &graph_json(&a.skeleton))?;
    write("skeleton_filtered.json", &graph_json(&a.filtered))?;
    write("skeleton.ply", &graph_ply(&a.skeleton))?;
    write("skeleton_filtered.ply", &graph_ply(&a.filtered))?;
    write("portals.json", &portals_json(&a))?;
    write("portals.obj", &portals_obj(&a))?;
    write_grid(&dir.join("mapping_filtered.u32"), &a.mapping.grid.data)?;
    write_grid(&dir.join("labels.u32"), &a.labelling.labels.data)?;
    write("grids.json", &grids_json(&a))?;
    let mut report = String::new();
    let [w, h, d] = a.spec.dims;
    let _ = writeln!(report, "grid {w}×{h}×{d}, voxel {:.4}, origin {:?}", a.spec.voxel, a.spec.origin);
    let _ = writeln!(report, "enclosed empty space: {:.1} % of the empty voxels", a.enclosed * 100.0);
    let _ = writeln!(report, "{}", space_kept(&a));
    let found = a.anchor_voxels.iter().filter(|v| v.is_some()).count();
    if !a.anchor_voxels.is_empty() {
        let _ = writeln!(report, "anchors: {found} of {} placed in the empty space", a.anchor_voxels.len());
    }
    let total: f64 = a.timings.iter().map(|t| t.1).sum();
    for (stage, secs) in &a.timings {
        let _ = writeln!(report, "{stage:<60} {secs:8.3} s");
    }
    let _ = writeln!(report, "{:<60} {total:8.3} s", "total");
    let _ = writeln!(report, "steps, each on its thread (a phase's steps overlap):");
    for (step, secs) in &a.steps {
        let _ = writeln!(report, "  {step:<58} {secs:8.3} s");
    }
    let _ = writeln!(
        report,
        "skeleton: {} nodes, {} edges; filtered: {} nodes, {} edges; {} labels, {} portals",
        a.skeleton.nodes.len(),
        a.skeleton.edges.len(),
        a.filtered.nodes.len(),
        a.filtered.edges.len(),
        a.labelling.count,
        a.portals.len()
    );
    write("report.txt", &report)?;
    if !quiet {
        eprint!("{report}");
    }
    Ok(a)
}

/// What the analysis kept of the empty space, in words.
pub fn space_kept(a: &Analysis) -> String {
    let what = match a.reach.kept {
        Kept::All => "every component (--keep-all-space)",
        Kept::Reached => "the components holding the camera or a light",
        Kept::LargestEnclosed => "no camera or light: the largest enclosed component",
        Kept::AllNothingEnclosed => "no camera or light, nothing enclosed: every component",
        Kept::AllSourceUnplaced => "every component: a camera or light has no empty voxel near it",
    };
    let dropped = a.reach.dropped;
    let share = dropped as f64 / (dropped + a.empty.data.iter().filter(|&&e| e).count()) as f64;
    format!("empty space kept: {what}; {dropped} empty voxels dropped ({:.1} %)", share * 100.0)
}

pub use skelight::guided::analysis::{scene_triangles, sources};

/// Which scene elements the skeleton must reach.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum AnchorKind {
    Lights,
    Camera,
}

/// Anchors for the chosen kinds of scene elements (see
/// [`skelight::guided::analysis::anchors`]).
pub fn anchors(scene: &Scene, kinds: &[AnchorKind]) -> Vec<Anchor> {
    use skelight::guided::analysis::AnchorKind as Kind;
    let kinds: Vec<Kind> = kinds
        .iter()
        .map(|k| match k {
            AnchorKind::Lights => Kind::Lights,
            AnchorKind::Camera => Kind::Camera,
        })
        .collect();
    skelight::guided::analysis::anchors(scene, &kinds)
}

/// `skeleton.json`: the graph's nodes (position, radius) and edges.
fn graph_json(g: &SkeletonGraph) -> String {
    #[derive(serde::Serialize)]
    struct Node {
        position: [f64; 3],
        radius: f64,
    }
    #[derive(serde::Serialize)]
    struct Graph<'a> {
        nodes: Vec<Node>,
        edges: &'a [[u32; 2]],
    }
    let nodes = g.nodes.iter().map(|n| Node { position: n.position, radius: n.radius }).collect();
    to_json(&Graph { nodes, edges: &g.edges })
}

/// Pretty JSON with a final newline (the values are plain numbers and strings: it cannot
/// fail).
fn to_json(value: &impl serde::Serialize) -> String {
    serde_json::to_string_pretty(value).expect("plain values serialize") + "\n"
}

/// ASCII PLY with vertices and edges (a line set most viewers show).
fn graph_ply(g: &SkeletonGraph) -> String {
    let mut s = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nproperty float radius\nelement edge {}\nproperty int vertex1\nproperty int vertex2\nend_header\n",
        g.nodes.len(),
        g.edges.len()
    );
    for n in &g.nodes {
        let [x, y, z] = n.position;
        let _ = writeln!(s, "{x} {y} {z} {}", n.radius);
    }
    for [a, b] in &g.edges {
        let _ = writeln!(s, "{a} {b}");
    }
    s
}

/// A grid as raw little-endian u32 values, x fastest, then y, then z.
fn write_grid(path: &Path, values: &[u32]) -> Result<()> {
    let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    skelight::imageio::write_file_atomically(path, &bytes)
        .map_err(anyhow::Error::msg)
        .with_context(|| format!("writing {}", path.display()))
}

/// Where the raw grids sit in the world and what their values mean.
fn grids_json(a: &Analysis) -> String {
    #[derive(serde::Serialize)]
    struct Grids {
        dims: [usize; 3],
        origin: [f64; 3],
        voxel: f64,
        layout: &'static str,
        #[serde(rename = "mapping_filtered.u32")]
        mapping_filtered: &'static str,
        #[serde(rename = "labels.u32")]
        labels: String,
    }
    to_json(&Grids {
        dims: a.spec.dims,
        origin: a.spec.origin,
        voxel: a.spec.voxel,
        layout: "little-endian u32, x fastest, then y, then z; voxel (x, y, z) spans origin + voxel * [x, x+1] (and so on)",
        mapping_filtered: "index + 1 of the node of skeleton_filtered.json each empty voxel maps to (Alg. 5); 0 for scene voxels and for empty pockets no node reaches",
        labels: format!("opening-forest region of each empty voxel, 1..{}; 0 for scene voxels", a.labelling.count),
    })
}

/// Every portal as an OBJ object of quads, one per 2-face between its regions.
fn portals_obj(a: &Analysis) -> String {
    let spec = &a.spec;
    let mut s = String::from("# opening portals: one object per pair of regions, one quad per face\n");
    let mut vertices = 0;
    for p in &a.portals {
        let _ = writeln!(s, "o portal_{}_{}", p.from, p.to);
        for &(v, axis) in &p.squares {
            let cell = spec.coords(v);
            let axis = axis as usize;
            let (u, t) = ((axis + 1) % 3, (axis + 2) % 3);
            for (du, dt) in [(0, 0), (1, 0), (1, 1), (0, 1)] {
                let mut q = [0.0; 3];
                for k in 0..3 {
                    let step = if k == axis {
                        1
                    } else if k == u {
                        du
                    } else if k == t {
                        dt
                    } else {
                        0
                    };
                    q[k] = spec.origin[k] + (cell[k] + step) as f64 * spec.voxel;
                }
                let _ = writeln!(s, "v {} {} {}", q[0], q[1], q[2]);
            }
            let _ = writeln!(s, "f {} {} {} {}", vertices + 1, vertices + 2, vertices + 3, vertices + 4);
            vertices += 4;
        }
    }
    s
}

/// `portals.json`: each portal's regions, face count, area, centroid and normal.
fn portals_json(a: &Analysis) -> String {
    #[derive(serde::Serialize)]
    struct Portal {
        regions: [u32; 2],
        faces: usize,
        area: f64,
        centroid: [f64; 3],
        normal: [f64; 3],
    }
    #[derive(serde::Serialize)]
    struct Portals {
        portals: Vec<Portal>,
    }
    let portals = a
        .portals
        .iter()
        .map(|p| Portal {
            regions: [p.from, p.to],
            faces: p.faces,
            area: p.area,
            centroid: p.centroid,
            normal: p.normal,
        })
        .collect();
    to_json(&Portals { portals })
}
