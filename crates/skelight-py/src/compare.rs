//! `skelight.compare`: an equal-time study's error curves as numpy arrays.

use std::time::Duration;

use numpy::ndarray::Array1;
use numpy::{IntoPyArray, PyReadonlyArray3};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use skelight::color::Rgb;
use skelight::imageio::Image;
use skelight::integrator::RenderOptions;

use crate::scene::Scene;
use crate::{error, LoadError};

/// Runs each estimator (`"name"` or `"name:param=value:…"`; `"gpu:pt"`, `"gpu:ibpt"` and
/// `"gpu:lt"` on the GPU, timed from when its kernels are ready) on `scene` for `time` seconds
/// and measures its error against `reference` (an EXR path or a float (H, W, 3) array)
/// after every pass, at most once per `every` seconds. Returns {name: {"seconds", "spp",
/// "mae", "rmse", "relmse" (arrays, one entry per measurement), "image", "preparation"}}.
#[pyfunction]
#[pyo3(signature = (scene, reference, integrators, time, every = 0.0, seed = 0, threads = 0))]
#[allow(clippy::too_many_arguments)]
pub fn compare<'py>(
    py: Python<'py>,
    scene: &Scene,
    reference: &Bound<'py, PyAny>,
    integrators: Vec<String>,
    time: f64,
    every: f64,
    seed: u64,
    threads: usize,
) -> PyResult<Bound<'py, PyDict>> {
    // Any float array becomes float32 (numpy's own conversion); anything else is a path.
    let as_f32 = reference
        .getattr("astype")
        .and_then(|astype| astype.call1(("float32",)))
        .and_then(|a| a.extract::<PyReadonlyArray3<f32>>());
    let reference = if let Ok(a) = as_f32 {
        let a = a.as_array();
        let (h, w, c) = a.dim();
        if c != 3 {
            return Err(error(format!("the reference array is {h}×{w}×{c}; expected (H, W, 3)")));
        }
        let pixels = (0..h * w).map(|i| Rgb::from_array([0, 1, 2].map(|k| a[[i / w, i % w, k]]))).collect();
        Image { width: w, height: h, pixels }
    } else {
        let path: std::path::PathBuf = reference.extract()?;
        Image::load(&path).map_err(|e| LoadError::new_err(e.to_string()))?
    };
    if let Some((count, (x, y))) = reference.non_finite() {
        return Err(error(format!("the reference has {count} NaN or infinite pixels (the first at x {x}, y {y})")));
    }
    if !(time > 0.0 && time.is_finite() && every >= 0.0 && every.is_finite()) {
        return Err(error("time must be a positive number of seconds and every at least 0"));
    }
    let opts = RenderOptions { spp: None, time: Some(Duration::from_secs_f64(time)), seed, threads };
    let lock = scene.scene.clone();
    let series = py
        .allow_threads(|| {
            let scene = lock.read().unwrap_or_else(|e| e.into_inner());
            skelight::compare::run_with(
                &scene,
                &integrators,
                &reference,
                &opts,
                Duration::from_secs_f64(every),
                |_, _| {},
                &mut skelight_gpu::job::CompareOnGpu,
            )
        })
        .map_err(error)?;
    let out = PyDict::new(py);
    for s in series {
        let d = PyDict::new(py);
        let column = |f: &dyn Fn(&skelight::compare::Point) -> f64| Array1::from_iter(s.points.iter().map(f));
        d.set_item("seconds", column(&|p| p.seconds).into_pyarray(py))?;
        d.set_item("spp", column(&|p| p.spp as f64).into_pyarray(py))?;
        d.set_item("mae", column(&|p| p.metrics.mae).into_pyarray(py))?;
        d.set_item("rmse", column(&|p| p.metrics.rmse).into_pyarray(py))?;
        d.set_item("relmse", column(&|p| p.metrics.relmse).into_pyarray(py))?;
        d.set_item("image", crate::render::array(py, &s.image))?;
        d.set_item("preparation", s.preparation)?;
        out.set_item(s.name, d)?;
    }
    Ok(out)
}
