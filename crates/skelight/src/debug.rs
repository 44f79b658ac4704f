//! `render --debug DIR` and Python's `render(..., debug=DIR)`: whatever the estimator shows
//! of itself ([`Integrator::debug_parts`], [`Integrator::debug_files`]), written the same way
//! for every estimator, so neither front end knows any estimator's pictures.

use std::path::{Path, PathBuf};

use crate::imageio::write_file_atomically;
use crate::integrator::diagnostics::{DebugFile, DebugParts};
use crate::integrator::Integrator;
use crate::job::{save_film, Job, JobError, Rendered};
use crate::scene::Scene;

fn create_dir(dir: &Path) -> Result<(), JobError> {
    std::fs::create_dir_all(dir).map_err(|e| JobError::Invalid(format!("creating {}: {e}", dir.display())))
}

/// Whether a render on `device`, sharded or not, can write the estimator's debug folder:
/// its pictures belong to a whole CPU render (the CLI's `--debug` and Python's `debug =`
/// ask this before the scene loads).
pub fn check_request(device: crate::job::Device, sharded: bool) -> Result<(), JobError> {
    if device != crate::job::Device::Cpu {
        return Err(JobError::Invalid(
            "the debug pictures belong to the CPU estimators: render them without the GPU".into(),
        ));
    }
    if sharded {
        return Err(JobError::Invalid(
            "a shard renders a slice of the samples: render the debug pictures without one".into(),
        ));
    }
    Ok(())
}

/// Whether `job` can render an estimator's parts: they need a sample count (and no time
/// budget), so that every part sees the same samples.
pub fn check_parts(job: &Job) -> Result<(), JobError> {
    if job.opts.spp.is_none() || job.opts.time.is_some() {
        return Err(JobError::Invalid(
            "--debug renders the estimator's parts and needs --spp without a time budget: every part must see the same samples".into(),
        ));
    }
    Ok(())
}

/// Renders each part of `parts` with `run` (the job's render with the part's estimator, the
/// same seed and samples each time, so that the images add up to the full render) into
/// DIR/STEM.exr (and .png, at `exposure`), and their means into DIR/CSV.
pub fn render_parts(
    dir: &Path,
    parts: DebugParts,
    exposure: f32,
    mut run: impl FnMut(Box<dyn Integrator>) -> Result<Rendered, JobError>,
) -> Result<Vec<PathBuf>, JobError> {
    create_dir(dir)?;
    let (csv_name, columns) = parts.table;
    let mut csv = format!("{columns},mean_r,mean_g,mean_b\n");
    let mut written = Vec::new();
    for part in parts.parts {
        let r = run(part.estimator)?;
        let path = dir.join(format!("{}.exr", part.stem));
        let m = save_film(&r.film, r.spp(), &path, exposure)?.mean();
        csv += &format!("{},{},{},{}\n", part.columns, m.r, m.g, m.b);
        written.push(path);
    }
    let path = dir.join(csv_name);
    write_file_atomically(&path, csv.as_bytes()).map_err(|e| JobError::Invalid(format!("{}: {e}", path.display())))?;
    written.push(path);
    Ok(written)
}

/// Writes the files `integrator` (prepared for `scene`, and rendered) offers of itself into
/// `dir`; returns their paths.
pub fn write_files(integrator: &dyn Integrator, scene: &Scene, dir: &Path) -> Result<Vec<PathBuf>, JobError> {
    let mut written = Vec::new();
    for file in integrator.debug_files(scene) {
        create_dir(dir)?;
        let path = dir.join(file.name());
        match &file {
            DebugFile::Png { image, .. } => image.save_png(&path, 0.0)?,
            DebugFile::Text { text, .. } => write_file_atomically(&path, text.as_bytes())
                .map_err(|e| JobError::Invalid(format!("{}: {e}", path.display())))?,
        }
        written.push(path);
    }
    Ok(written)
}
