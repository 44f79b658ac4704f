//! `skelight.render`, `skelight.Render` and `skelight.merge`: a render job run with the GIL
//! released, its film kept (so shards merge exactly), pickled as a shard's bytes.

use std::time::Duration;

use numpy::ndarray::Array3;
use numpy::{IntoPyArray, PyArray3};
use pyo3::exceptions::PyKeyboardInterrupt;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyTuple};
use skelight::film::Film;
use skelight::imageio::Image;
use skelight::job::{Device, Job, JobError, JobSpec};
use skelight::shard::{self, Manifest, Shard, ShardOutput};

use crate::scene::Scene;
use crate::{error, LoadError};

/// A finished render: its image as numpy (`np.asarray(r)` or `r.image`, float32 (H, W, 3)),
/// the per-pixel variance of the estimate, the samples it holds, and for a shard its
/// place in the whole render. Pickles (for Dask) as a shard's bytes, film included.
#[pyclass(module = "skelight", frozen)]
pub struct Render {
    film: Film,
    manifest: Manifest,
    /// Whether it is one shard of several (otherwise the whole render, shard 0/1).
    sharded: bool,
    seconds: f64,
    preparation_seconds: f64,
}

pub(crate) fn array<'py>(py: Python<'py>, img: &Image) -> Bound<'py, PyArray3<f32>> {
    let data: Vec<f32> = img.pixels.iter().flat_map(|p| p.to_array()).collect();
    Array3::from_shape_vec((img.height, img.width, 3), data).expect("pixels × 3 values").into_pyarray(py)
}

#[pymethods]
impl Render {
    /// The image, float32 (H, W, 3), linear RGB.
    #[getter]
    fn image<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray3<f32>> {
        array(py, &self.film.image())
    }
    /// Per-pixel variance of the pixel estimate (sample variance / n), float32 (H, W, 3).
    #[getter]
    fn variance<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray3<f32>> {
        array(py, &self.film.variance_image())
    }
    /// Samples per pixel it holds.
    #[getter]
    fn spp(&self) -> u32 {
        self.manifest.samples.len() as u32
    }
    /// The sample indices it holds, (first, end).
    #[getter]
    fn samples(&self) -> (u32, u32) {
        (self.manifest.samples.start, self.manifest.samples.end)
    }
    /// (K, N) for shard K of N; None for a whole render (which pickles as shard (0, 1)).
    #[getter]
    fn shard(&self) -> Option<(u32, u32)> {
        self.sharded.then_some((self.manifest.shard.index, self.manifest.shard.count))
    }
    /// Identifies the render (scene, estimator and parameters, seed, size, depth).
    #[getter]
    fn key(&self) -> String {
        self.manifest.render.clone()
    }
    /// Wall time of the render, preparation included (0 after a merge).
    #[getter]
    fn seconds(&self) -> f64 {
        self.seconds
    }
    #[getter]
    fn preparation_seconds(&self) -> f64 {
        self.preparation_seconds
    }
    #[pyo3(signature = (dtype = None, copy = None))]
    fn __array__<'py>(
        &self,
        py: Python<'py>,
        dtype: Option<Bound<'py, PyAny>>,
        copy: Option<bool>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let _ = copy;
        let a = self.image(py).into_any();
        match dtype {
            Some(t) if !t.is_none() => a.call_method1("astype", (t,)),
            _ => Ok(a),
        }
    }
    /// Writes PATH (.exr; a shard with its manifest and film, for `skelight merge`) and a
    /// PNG beside it, each atomically.
    #[pyo3(signature = (path, exposure = 0.0))]
    fn save(&self, path: std::path::PathBuf, exposure: f32) -> PyResult<()> {
        if self.sharded {
            self.output().save(&path, exposure).map_err(error)?;
        } else {
            skelight::job::save_film(&self.film, self.spp(), &path, exposure).map_err(error)?;
        }
        Ok(())
    }
    /// Self-contained bytes (film and manifest); `Render.from_bytes` reads them back.
    fn to_bytes<'py>(&self, py: Python<'py>) -> Bound<'py, PyBytes> {
        PyBytes::new(py, &self.output().to_bytes())
    }
    #[staticmethod]
    fn from_bytes(data: &[u8]) -> PyResult<Render> {
        let out = ShardOutput::from_bytes("bytes", data).map_err(error)?;
        Ok(Render { film: out.film, manifest: out.manifest, sharded: true, seconds: 0.0, preparation_seconds: 0.0 })
    }
    /// Reads a shard written by `save` or `skelight render --shard`.
    #[staticmethod]
    fn load(path: std::path::PathBuf) -> PyResult<Render> {
        let out = ShardOutput::load(&path).map_err(|e| LoadError::new_err(e.to_string()))?;
        Ok(Render { film: out.film, manifest: out.manifest, sharded: true, seconds: 0.0, preparation_seconds: 0.0 })
    }
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyTuple>)> {
        let py = slf.py();
        let from_bytes = py.get_type::<Render>().getattr("from_bytes")?;
        Ok((from_bytes, PyTuple::new(py, [slf.get().to_bytes(py)])?))
    }
    fn __repr__(&self) -> String {
        let shard = self.shard().map(|(k, n)| format!(", shard {k}/{n}")).unwrap_or_default();
        format!("<skelight.Render {}×{}, {} spp{shard}>", self.film.width, self.film.height, self.spp())
    }
}

impl Render {
    fn output(&self) -> ShardOutput {
        ShardOutput { film: self.film.clone(), manifest: self.manifest.clone() }
    }
}

/// Turns a params dict into NAME=VALUE pairs (booleans as true/false).
fn param_pairs(params: Option<&Bound<'_, PyDict>>) -> PyResult<Vec<(String, String)>> {
    let mut pairs = Vec::new();
    if let Some(p) = params {
        for (k, v) in p.iter() {
            let value = if v.is_instance_of::<pyo3::types::PyBool>() {
                v.extract::<bool>()?.to_string()
            } else {
                v.str()?.to_string()
            };
            pairs.push((k.extract::<String>()?, value));
        }
    }
    Ok(pairs)
}

/// The key a render of `scene` with these settings would carry (`Render.key`): what
/// `merge` and resumed references compare, to refuse shards of another render.
#[pyfunction]
#[pyo3(signature = (scene, integrator = "pt", spp = None, seed = 0, params = None, shard = None, device = "cpu"))]
pub fn render_key(
    scene: &Scene,
    integrator: &str,
    spp: Option<u32>,
    seed: u64,
    params: Option<&Bound<'_, PyDict>>,
    shard: Option<(u32, u32)>,
    device: &str,
) -> PyResult<String> {
    let pairs = param_pairs(params)?;
    let device = parse_device(device)?;
    let shard = shard.map(|(k, n)| Shard::new(k, n)).transpose().map_err(error)?;
    let spec =
        JobSpec { integrator: integrator.to_string(), params: pairs, spp, seed, shard, device, ..Default::default() };
    let s = scene.read();
    let job = Job::new(&s, scene.label(), &spec).map_err(error)?;
    if device == Device::Gpu {
        skelight_gpu::job::kernels_for(&job.params).map_err(error)?;
    }
    Ok(job.key(&s))
}

/// `device = "cpu"` or `"gpu"`.
fn parse_device(device: &str) -> PyResult<Device> {
    device.parse().map_err(error)
}

/// Renders `scene` with an estimator of the registry (`skelight.integrators()` lists them
/// with their parameters) and returns a `Render`. Give `spp` or `time` (seconds); `shard`
/// = (K, N) renders shard K of N of the `spp` samples (merge them with `skelight.merge`).
/// `progress`, if given, is called after every pass with a dict (spp, target, seconds,
/// samples_per_second); an exception it raises stops the render and propagates. The GIL
/// is released while rendering; Ctrl-C stops the render (KeyboardInterrupt) within a pass.
/// The render's key names the scene by its content, not its path, so shards rendered from
/// copies of one file at different paths merge. `device = "gpu"` renders pt, ibpt or lt on the
/// first Vulkan adapter (skelight_gpu; `threads` unused): the same samples, shards and time
/// budget, its key naming the device (GPU shards merge with GPU shards only). `debug`, a
/// folder, writes what the estimator shows of itself there, as `skelight render --debug`
/// does (its parts, rendered with the same samples, and pictures of its internals).
#[pyfunction]
#[pyo3(signature = (scene, integrator = "pt", spp = None, time = None, seed = 0, params = None, shard = None, threads = 0, progress = None, device = "cpu", debug = None))]
#[allow(clippy::too_many_arguments)]
pub fn render(
    py: Python<'_>,
    scene: &Scene,
    integrator: &str,
    spp: Option<u32>,
    time: Option<f64>,
    seed: u64,
    params: Option<&Bound<'_, PyDict>>,
    shard: Option<(u32, u32)>,
    threads: usize,
    progress: Option<PyObject>,
    device: &str,
    debug: Option<std::path::PathBuf>,
) -> PyResult<Render> {
    let pairs = param_pairs(params)?;
    let device = parse_device(device)?;
    if debug.is_some() {
        skelight::debug::check_request(device, shard.is_some()).map_err(|e| error(format!("debug = …: {e}")))?;
    }
    let time = match time {
        Some(t) if !(t > 0.0 && t.is_finite() && t < 1e9) => {
            return Err(error(format!("time = {t}: give a positive number of seconds")))
        }
        Some(t) => Some(Duration::from_secs_f64(t)),
        None => None,
    };
    let shard = shard.map(|(k, n)| Shard::new(k, n)).transpose().map_err(error)?;
    let spec = JobSpec { integrator: integrator.to_string(), params: pairs, spp, time, seed, threads, shard, device };
    let scene_lock = scene.scene.clone();
    let label = scene.label();
    let mut raised: Option<PyErr> = None;
    let result = py.allow_threads(|| {
        let scene = scene_lock.read().unwrap_or_else(|e| e.into_inner());
        let mut job = Job::new(&scene, label.clone(), &spec)?;
        if let Some(dir) = &debug {
            let parts = job.integrator.debug_parts(&scene).map_err(|e| JobError::Invalid(format!("debug: {e}")))?;
            if let Some(parts) = parts {
                skelight::debug::check_parts(&job)?;
                let run = |estimator| {
                    let mut part = Job::new(&scene, label.clone(), &spec)?;
                    part.integrator = estimator;
                    part.run(&scene, None, |_, _| Ok(()))
                };
                skelight::debug::render_parts(dir, parts, 0.0, run)?;
            }
        }
        let on_pass = |p: &skelight::integrator::Progress, _: &Film| {
            Python::with_gil(|py| {
                let outcome = py.check_signals().and_then(|()| match &progress {
                    Some(f) => {
                        let d = PyDict::new(py);
                        d.set_item("spp", p.spp_done)?;
                        d.set_item("target", p.spp_target)?;
                        d.set_item("seconds", p.elapsed.as_secs_f64())?;
                        d.set_item("samples_per_second", p.samples_per_second)?;
                        f.call1(py, (d,)).map(|_| ())
                    }
                    None => Ok(()),
                });
                outcome.map_err(|e| {
                    let message = if e.is_instance_of::<PyKeyboardInterrupt>(py) { "interrupted" } else { "stopped" };
                    raised = Some(e);
                    JobError::Stopped(message.into())
                })
            })
        };
        // The CPU's estimator or, for device = "gpu", the GPU's kernels (the same job, its
        // shard's samples or time budget).
        let (mut renderer, _) = skelight_gpu::job::renderer_for(&job, &scene)?;
        let mut on_pass = on_pass;
        let rendered = renderer(&mut job, &scene, None, &mut on_pass)?;
        if let Some(dir) = &debug {
            skelight::debug::write_files(job.integrator.as_ref(), &scene, dir)?;
        }
        Ok::<_, JobError>((rendered, job.key(&scene)))
    });
    if let Some(e) = raised {
        return Err(e);
    }
    let (r, key) = result.map_err(|e| match e {
        JobError::Load(e) => LoadError::new_err(e.to_string()),
        e => error(e),
    })?;
    let sharded = r.manifest.is_some();
    let manifest = r.manifest.clone().unwrap_or(Manifest {
        render: key,
        shard: Shard { index: 0, count: 1 },
        samples: r.samples.clone(),
    });
    Ok(Render {
        film: r.film,
        manifest,
        sharded,
        seconds: r.elapsed.as_secs_f64(),
        preparation_seconds: r.preparation.elapsed.as_secs_f64(),
    })
}

/// Merges the shards of one render (Render objects, or paths of shard EXRs) into the whole
/// render: refuses shards of different renders, a shard given twice and a missing one.
/// The result equals the single render of the same seed and spp up to the order of f64
/// sums (in float32, almost every pixel is bit-identical; the rest differ in the last bit).
#[pyfunction]
pub fn merge(py: Python<'_>, parts: Vec<Bound<'_, PyAny>>) -> PyResult<Render> {
    let mut outputs = Vec::new();
    for (i, p) in parts.iter().enumerate() {
        if let Ok(r) = p.downcast::<Render>() {
            outputs.push((format!("part {i} ({})", r.get().__repr__()), r.get().output()));
        } else {
            let path: std::path::PathBuf = p.extract()?;
            let out = py.allow_threads(|| ShardOutput::load(&path)).map_err(|e| LoadError::new_err(e.to_string()))?;
            outputs.push((path.display().to_string(), out));
        }
    }
    let merged = py.allow_threads(|| shard::merge(outputs)).map_err(error)?;
    let manifest = Manifest { render: merged.render, shard: Shard { index: 0, count: 1 }, samples: 0..merged.spp };
    Ok(Render { film: merged.film, manifest, sharded: false, seconds: 0.0, preparation_seconds: 0.0 })
}

/// Reads an image (EXR, PNG, JPEG) as float32 (H, W, 3), linear RGB.
#[pyfunction]
pub fn load_image(py: Python<'_>, path: std::path::PathBuf) -> PyResult<Bound<'_, PyArray3<f32>>> {
    let img = py.allow_threads(|| Image::load(&path)).map_err(|e| LoadError::new_err(e.to_string()))?;
    Ok(array(py, &img))
}

/// The estimators: {name: {"doc": …, "params": {name: (default, doc)}}}.
#[pyfunction]
pub fn integrators(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let out = PyDict::new(py);
    for name in skelight::estimators::registry::names() {
        let e = skelight::estimators::registry::find(name).map_err(error)?;
        let d = PyDict::new(py);
        d.set_item("doc", e.doc)?;
        let params = PyDict::new(py);
        for p in e.params {
            params.set_item(p.name, (p.default.to_string(), p.doc))?;
        }
        d.set_item("params", params)?;
        out.set_item(name, d)?;
    }
    Ok(out)
}
