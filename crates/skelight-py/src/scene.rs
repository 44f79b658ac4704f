//! `skelight.Scene`: a loaded scene, what it contains, and its empty-space analysis as numpy
//! arrays.

use std::path::PathBuf;
use std::sync::{Arc, RwLock, RwLockReadGuard};

use numpy::ndarray::{Array1, Array2, Array3};
use numpy::IntoPyArray;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use skelight::guided::analysis::{analysis_settings, scene_triangles, GuideSettings};

use crate::{error, LoadError};

/// A scene loaded from a file (Mitsuba XML, glTF, TOML, OBJ, PLY) or the embedded default.
/// Render it with `skelight.render(scene, …)`; change its resolution or depth with
/// `set_resolution` and `max_depth` before rendering.
#[pyclass(module = "skelight", frozen)]
pub struct Scene {
    pub(crate) scene: Arc<RwLock<skelight::scene::Scene>>,
    /// The file it came from (None: the default scene), which labels renders and shards.
    pub(crate) path: Option<PathBuf>,
}

impl Scene {
    pub(crate) fn read(&self) -> RwLockReadGuard<'_, skelight::scene::Scene> {
        self.scene.read().unwrap_or_else(|e| e.into_inner())
    }

    /// The scene to change, refused while a render reads it (waiting would deadlock: the
    /// render takes the GIL back after every pass while holding the scene).
    fn write(&self) -> PyResult<std::sync::RwLockWriteGuard<'_, skelight::scene::Scene>> {
        self.scene.try_write().map_err(|_| error("the scene is being rendered; change it once the render is done"))
    }

    /// Names the scene in manifests and reports, as the CLI does.
    pub(crate) fn label(&self) -> String {
        self.path
            .as_ref()
            .map(|p| p.display().to_string())
            .unwrap_or_else(|| "default scene (two rooms, door ajar)".into())
    }
}

/// Loads a scene file; keyword arguments substitute its parameters (Mitsuba's -D name=value).
/// Raises skelight.LoadError naming the file and line of what is wrong.
#[pyfunction]
#[pyo3(signature = (path, **defines))]
pub fn load_file(py: Python<'_>, path: PathBuf, defines: Option<&Bound<'_, PyDict>>) -> PyResult<Scene> {
    let mut defs = Vec::new();
    if let Some(d) = defines {
        for (k, v) in d.iter() {
            defs.push((k.extract::<String>()?, v.str()?.to_string()));
        }
    }
    let p = path.clone();
    let scene = py
        .allow_threads(move || skelight::scene::load::load(&p, &defs))
        .map_err(|e| LoadError::new_err(e.to_string()))?;
    Ok(Scene { scene: Arc::new(RwLock::new(scene)), path: Some(path) })
}

/// The embedded default scene: two rooms joined by a door left ajar.
#[pyfunction]
pub fn default_scene() -> Scene {
    Scene { scene: Arc::new(RwLock::new(skelight::scene::builtin::two_rooms())), path: None }
}

#[pymethods]
impl Scene {
    #[getter]
    fn path(&self) -> Option<PathBuf> {
        self.path.clone()
    }
    #[getter]
    fn width(&self) -> usize {
        self.read().settings.width
    }
    #[getter]
    fn height(&self) -> usize {
        self.read().settings.height
    }
    #[getter]
    fn triangles(&self) -> usize {
        self.read().triangle_count()
    }
    #[getter]
    fn lights(&self) -> usize {
        self.read().lights.len()
    }
    /// The loader's warnings (ignored elements, substitutions made).
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.read().warnings.clone()
    }
    /// The sample count the file asks for.
    #[getter]
    fn spp(&self) -> u32 {
        self.read().settings.spp
    }
    /// Longest path in segments (-1: unbounded).
    #[getter]
    fn get_max_depth(&self) -> i32 {
        self.read().settings.max_depth
    }
    #[setter]
    fn set_max_depth(&self, depth: i32) -> PyResult<()> {
        if depth < -1 {
            return Err(error("max_depth must be -1 (unbounded) or at least 0"));
        }
        self.write()?.settings.max_depth = depth;
        Ok(())
    }
    /// Renders at `width`×`height` from now on (the field of view is kept).
    fn set_resolution(&self, width: i64, height: i64) -> PyResult<()> {
        skelight::scene::check_resolution(width, height).map_err(error)?;
        self.write()?.set_resolution(width as usize, height as usize);
        Ok(())
    }
    /// The camera: position, forward direction, horizontal and vertical field of view
    /// (degrees).
    #[getter]
    fn camera<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = self.read();
        let c = &s.camera;
        let d = PyDict::new(py);
        d.set_item("position", [c.position.x, c.position.y, c.position.z])?;
        d.set_item("forward", [c.forward.x, c.forward.y, c.forward.z])?;
        let fov = |t: f32| 2.0 * t.atan().to_degrees();
        d.set_item("fov_x", fov(c.tan_half.x))?;
        d.set_item("fov_y", fov(c.tan_half.y))?;
        Ok(d)
    }
    /// Everything above in one dict.
    fn info<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyDict>> {
        let py = slf.py();
        let me = slf.get();
        let d = PyDict::new(py);
        d.set_item("path", me.path())?;
        d.set_item("width", me.width())?;
        d.set_item("height", me.height())?;
        d.set_item("triangles", me.triangles())?;
        d.set_item("lights", me.lights())?;
        d.set_item("spp", me.spp())?;
        d.set_item("max_depth", me.get_max_depth())?;
        d.set_item("camera", me.camera(py)?)?;
        d.set_item("warnings", PyList::new(py, me.warnings())?)?;
        Ok(d)
    }
    /// The empty-space analysis at `resolution` voxels on the box's longest side, with the
    /// lights and camera as anchors (as skelpt and skelbpt run it): the filtered skeleton's
    /// `nodes` (N, 3) and `radii` (N,), its `edges` (E, 2), the `mapping` grid (node + 1 of
    /// every empty voxel, 0 elsewhere) and the opening-forest `labels`, both (D, H, W)
    /// indexed [z, y, x], with the grid's `origin` and `voxel` size, and the stage timings.
    #[pyo3(signature = (resolution = 128))]
    fn skeleton<'py>(&self, py: Python<'py>, resolution: usize) -> PyResult<Bound<'py, PyDict>> {
        if !(8..=2048).contains(&resolution) {
            return Err(error(format!("resolution {resolution}: use 8 to 2048 voxels on the longest side")));
        }
        let scene = self.scene.clone();
        let a = py
            .allow_threads(move || {
                let scene = scene.read().unwrap_or_else(|e| e.into_inner());
                let settings = analysis_settings(&scene, &GuideSettings { resolution, ..Default::default() });
                skelight_shape::pipeline::analyse(&scene_triangles(&scene), &settings)
            })
            .map_err(error)?;
        let g = &a.filtered;
        let nodes = Array2::from_shape_fn((g.nodes.len(), 3), |(i, c)| g.nodes[i].position[c]);
        let radii = Array1::from_iter(g.nodes.iter().map(|n| n.radius));
        let edges = Array2::from_shape_fn((g.edges.len(), 2), |(i, c)| g.edges[i][c]);
        let [w, h, d] = a.spec.dims;
        let grid = |data: &[u32]| Array3::from_shape_vec((d, h, w), data.to_vec()).map_err(error);
        let out = PyDict::new(py);
        out.set_item("nodes", nodes.into_pyarray(py))?;
        out.set_item("radii", radii.into_pyarray(py))?;
        out.set_item("edges", edges.into_pyarray(py))?;
        out.set_item("mapping", grid(&a.mapping.grid.data)?.into_pyarray(py))?;
        out.set_item("labels", grid(&a.labelling.labels.data)?.into_pyarray(py))?;
        out.set_item("origin", a.spec.origin)?;
        out.set_item("voxel", a.spec.voxel)?;
        out.set_item("timings", a.timings.iter().map(|(s, t)| (s.to_string(), *t)).collect::<Vec<_>>())?;
        Ok(out)
    }
    fn __repr__(&self) -> String {
        let s = self.read();
        format!(
            "<skelight.Scene {}: {}×{}, {} triangles, {} lights>",
            self.label(),
            s.settings.width,
            s.settings.height,
            s.triangle_count(),
            s.lights.len()
        )
    }
}
