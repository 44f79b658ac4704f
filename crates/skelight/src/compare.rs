//! Equal-time runs of several estimators against a reference: the error after every pass,
//! and the time each takes to reach a target error. `skelight compare` writes its report
//! from these curves; the Python package returns them as arrays.

use std::time::Duration;

use crate::eval::{self, Metrics};
use crate::film::Film;
use crate::imageio::Image;
use crate::integrator::{self, Progress, RenderOptions, RenderResult};
use crate::job::JobError;
use crate::scene::Scene;

/// One error measurement during a run.
#[derive(Clone, Debug)]
pub struct Point {
    pub iteration: usize,
    pub spp: u32,
    pub seconds: f64,
    pub metrics: Metrics,
}

/// One estimator's run: its error curve and final image.
pub struct Series {
    pub name: String,
    pub points: Vec<Point>,
    pub image: Image,
    /// Seconds of the estimator's preparation (part of its time budget).
    pub preparation: f64,
}

/// A renderer outside this crate for the names it knows (the GPU's `gpu:NAME`).
pub trait External {
    /// `None` for a name it does not know (rendered here); otherwise whether it can render
    /// the name on `scene`. Called for every name before any is rendered, so that a bad name
    /// fails at once rather than after the runs before it.
    fn check(&mut self, name: &str, scene: &Scene) -> Option<Result<(), JobError>>;

    /// Renders a name `check` accepted with `opts` (a time budget), calling `on_pass` after
    /// every pass (false: stop). Its errors need not name the entry: [`run_with`] does.
    fn render(
        &mut self,
        name: &str,
        scene: &Scene,
        opts: &RenderOptions,
        on_pass: &mut dyn FnMut(&Progress, &Film) -> bool,
    ) -> Result<RenderResult, JobError>;
}

/// No external renderer: every name is rendered here.
impl External for () {
    fn check(&mut self, _: &str, _: &Scene) -> Option<Result<(), JobError>> {
        None
    }

    fn render(
        &mut self,
        _: &str,
        _: &Scene,
        _: &RenderOptions,
        _: &mut dyn FnMut(&Progress, &Film) -> bool,
    ) -> Result<RenderResult, JobError> {
        Err(JobError::Invalid("no renderer outside the CPU's".into()))
    }
}

/// Runs each estimator (`name` or `name:param=value:…`) in turn for `base.time`, measuring
/// the error against `reference` after every pass (at most once per `every`); `on_pass`
/// sees each estimator's progress.
pub fn run(
    scene: &Scene,
    names: &[String],
    reference: &Image,
    base: &RenderOptions,
    every: Duration,
    on_pass: impl FnMut(&str, &Progress),
) -> Result<Vec<Series>, JobError> {
    run_with(scene, names, reference, base, every, on_pass, &mut ())
}

/// [`run`], the names `external` knows rendered by it. Every name is checked before the
/// first run starts.
pub fn run_with(
    scene: &Scene,
    names: &[String],
    reference: &Image,
    base: &RenderOptions,
    every: Duration,
    mut on_pass: impl FnMut(&str, &Progress),
    external: &mut dyn External,
) -> Result<Vec<Series>, JobError> {
    let time = base.time.ok_or_else(|| JobError::Invalid("a comparison needs a time budget".into()))?;
    eval::metrics(reference, reference).map_err(|_| JobError::Invalid("the reference has no pixels".into()))?;
    if (scene.settings.width, scene.settings.height) != (reference.width, reference.height) {
        return Err(JobError::Invalid(format!(
            "the scene renders {}×{} but the reference is {}×{}",
            scene.settings.width, scene.settings.height, reference.width, reference.height
        )));
    }
    if names.is_empty() {
        return Err(JobError::Invalid("a comparison needs at least one estimator".into()));
    }
    // Each name's estimator, or the external renderer's word on it, before any run. An
    // entry's errors, here and in its run, are named after it here (JobError::about) and
    // nowhere else.
    let mut estimators = Vec::with_capacity(names.len());
    for name in names {
        let estimator = match external.check(name, scene) {
            Some(checked) => checked.map(|()| None),
            None => crate::estimators::registry::parse_spec(name)
                .and_then(|(estimator, params)| crate::estimators::registry::create(&estimator, &params))
                .map(Some)
                .map_err(JobError::from),
        };
        estimators.push(estimator.map_err(|e| e.about(name))?);
    }
    let mut out: Vec<Series> = Vec::new();
    for (name, estimator) in names.iter().zip(estimators) {
        // The same estimator twice (e.g. to see run-to-run spread) gets distinct names.
        let repeats = out.iter().filter(|s| s.name == *name || s.name.starts_with(&format!("{name}#"))).count();
        let label = if repeats == 0 { name.clone() } else { format!("{name}#{}", repeats + 1) };
        let opts = RenderOptions { spp: None, time: Some(time), ..base.clone() };
        let mut points = Vec::new();
        let mut last: Option<f64> = None;
        let mut measure = |p: &Progress, film: &Film| {
            let t = p.elapsed.as_secs_f64();
            if last.is_none_or(|l| t - l >= every.as_secs_f64()) {
                let metrics = eval::metrics(&film.image(), reference).expect("sizes checked above");
                points.push(Point { iteration: points.len(), spp: p.spp_done, seconds: t, metrics });
                last = Some(t);
            }
            on_pass(name, p);
            true
        };
        let r = match estimator {
            Some(mut integ) => {
                integrator::render(scene, integ.as_mut(), &opts, None, &mut measure).map_err(JobError::from)
            }
            None => external.render(name, scene, &opts, &mut measure),
        }
        .map_err(|e| e.about(name))?;
        let image = r.film.image();
        let metrics = eval::metrics(&image, reference).expect("sizes checked above");
        if points.last().is_none_or(|p| p.spp != r.spp) {
            points.push(Point { iteration: points.len(), spp: r.spp, seconds: r.elapsed.as_secs_f64(), metrics });
        }
        out.push(Series { name: label, points, image, preparation: r.preparation.elapsed.as_secs_f64() });
    }
    Ok(out)
}

/// The error a study ranks by (relMSE).
pub fn metric(p: &Point) -> f64 {
    p.metrics.relmse
}

/// Time at which a series first reaches `target` error (log-log interpolation).
pub fn time_to_error(points: &[Point], target: f64) -> Option<f64> {
    let mut prev: Option<&Point> = None;
    for p in points {
        if metric(p) <= target {
            return Some(match prev {
                Some(q) if metric(q) > target && metric(p) > 0.0 && q.seconds > 0.0 => {
                    let f = (target.ln() - metric(q).ln()) / (metric(p).ln() - metric(q).ln());
                    (q.seconds.ln() + f * (p.seconds.ln() - q.seconds.ln())).exp()
                }
                _ => p.seconds,
            });
        }
        prev = Some(p);
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::color::rgb;

    /// The two rooms at 8×8, a flat reference and a time budget of `ms` for each entry.
    fn small(ms: u64) -> (Scene, Image, RenderOptions) {
        let mut scene = crate::scene::builtin::two_rooms();
        scene.set_resolution(8, 8);
        let reference = Image { width: 8, height: 8, pixels: vec![rgb(1.0, 1.0, 1.0); 64] };
        (scene, reference, RenderOptions { spp: None, time: Some(Duration::from_millis(ms)), seed: 1, threads: 1 })
    }

    /// Every name is checked before the first run: a bad one after a long run would lose it.
    #[test]
    fn a_bad_name_fails_before_any_run() {
        let (scene, reference, opts) = small(200);
        for bad in ["nosuch", "pt:nosuch=1", "bpt:heuristic=nosuch"] {
            let mut passes = 0;
            let names = ["pt".to_string(), bad.to_string()];
            let r = run(&scene, &names, &reference, &opts, Duration::ZERO, |_, _| passes += 1);
            let message = r.err().map(|e| e.to_string()).unwrap_or_default();
            assert!(message.contains("nosuch"), "{bad}: {message}");
            assert_eq!(passes, 0, "{bad}: pt ran before the bad name was refused");
        }
        assert!(run(&scene, &[], &reference, &opts, Duration::ZERO, |_, _| {}).is_err());
    }

    /// An external renderer that accepts `ext:…` names and fails their runs.
    struct Failing;

    impl External for Failing {
        fn check(&mut self, name: &str, _: &Scene) -> Option<Result<(), JobError>> {
            name.starts_with("ext:").then_some(Ok(()))
        }

        fn render(
            &mut self,
            _: &str,
            _: &Scene,
            _: &RenderOptions,
            _: &mut dyn FnMut(&Progress, &Film) -> bool,
        ) -> Result<RenderResult, JobError> {
            Err(JobError::Device("lost the device".into()))
        }
    }

    /// A run's error names its entry (the renderer's own message need not), keeping its kind.
    #[test]
    fn a_failed_run_names_its_entry() {
        let (scene, reference, opts) = small(50);
        let names = ["pt".to_string(), "ext:a".to_string()];
        let r = run_with(&scene, &names, &reference, &opts, Duration::ZERO, |_, _| {}, &mut Failing);
        match r {
            Err(JobError::Device(message)) => assert_eq!(message, "ext:a: lost the device"),
            other => panic!("expected the device's error named after its entry, got {:?}", other.err()),
        }
    }
}
