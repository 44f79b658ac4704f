//! The estimator registry: one table of every estimator with its one-line doc, its typed
//! parameters and its constructor (pbrt-v4's `Integrator::Create` from a parameter
//! dictionary). The command line, a scene's `<integrator>` properties, `--help` and the
//! tests all read it, so adding an estimator here is all it takes to offer it everywhere.

use super::resampling::{IcBpt, SkeletonBpt, ICBPT_PARAMS, SKELBPT_PARAMS};
use super::{bpt, ibpt, lt, portalpt, pt, skelpt};
use crate::integrator::params::{self, ParamError, ParamSpec, Params};
use crate::integrator::Integrator;
use crate::paths::bidir::{PixelSampler, Recorded};
use crate::paths::mis::Heuristic;

/// One estimator as the registry offers it.
pub struct Estimator {
    pub name: &'static str,
    /// Other names scene files use for it (Mitsuba's `path`, `bdpt`, `ptracer`).
    pub aliases: &'static [&'static str],
    pub doc: &'static str,
    pub params: &'static [ParamSpec],
    /// Builds it from checked parameters.
    pub create: fn(&Params) -> Box<dyn Integrator>,
}

impl Estimator {
    /// Whether a scene's `<integrator type=…>` names this estimator.
    pub fn answers_to(&self, name: &str) -> bool {
        self.name == name || self.aliases.contains(&name)
    }
}

/// Every estimator, in the order help texts list them.
pub static ESTIMATORS: &[Estimator] = &[
    Estimator {
        name: "pt",
        aliases: &["path"],
        doc: "path tracing with next-event estimation and MIS on emitter hits",
        params: &[],
        create: |_| Box::new(pt::PathTracer::default()),
    },
    Estimator {
        name: "lt",
        aliases: &["ptracer"],
        doc: "light tracing: light paths connected to the camera",
        params: &[],
        create: |_| Box::new(lt::LightTracer::default()),
    },
    Estimator {
        name: "bpt",
        aliases: &["bdpt"],
        doc: "bidirectional path tracing, every (s, t) strategy, exact MIS",
        params: &[params::MIS_HEURISTIC],
        create: |p| {
            let heuristic = Heuristic::parse(p.choice("heuristic")).unwrap_or_default();
            Box::new(bpt::Bpt { sampler: PixelSampler { max_depth: None, heuristic, only: Recorded::All } })
        },
    },
    Estimator {
        name: "ibpt",
        aliases: &[],
        doc: "instant BPT: a path-tracing and a light-tracing walk joined by one-float MIS",
        params: &[],
        create: |_| Box::new(ibpt::InstantBpt),
    },
    Estimator {
        name: "skelpt",
        aliases: &[],
        doc: "path tracing guided by the skeleton of the empty space towards lit places (thesis ch. 9)",
        params: skelpt::PARAMS,
        create: |p| Box::new(skelpt::SkeletonPathTracer::from_params(p)),
    },
    Estimator {
        name: "portalpt",
        aliases: &[],
        doc: "path tracing guided through the opening portals of the empty space towards lit regions (thesis ch. 10.4)",
        params: portalpt::PARAMS,
        create: |p| Box::new(portalpt::PortalPathTracer::from_params(p)),
    },
    Estimator {
        name: "skelbpt",
        aliases: &[],
        doc:
            "bpt whose connections resample light vertices with distributions cached at skeleton nodes (thesis ch. 11)",
        params: SKELBPT_PARAMS,
        create: |p| Box::new(SkeletonBpt::from_params(p)),
    },
    Estimator {
        name: "icbpt",
        aliases: &[],
        doc: "bpt whose connections resample light vertices with distributions cached at importance records \
              (Georgiev et al. 2012 adapted to bpt, thesis section 11.5)",
        params: ICBPT_PARAMS,
        create: |p| Box::new(IcBpt::from_params(p)),
    },
];

/// The registry entry for `name` (or an alias).
pub fn find(name: &str) -> Result<&'static Estimator, ParamError> {
    ESTIMATORS
        .iter()
        .find(|e| e.answers_to(name))
        .ok_or_else(|| ParamError::UnknownEstimator { name: name.to_string(), available: names().join(", ") })
}

/// Builds `name` with its defaults overridden by `params` (`name`, `value` pairs, later
/// ones winning).
pub fn create(name: &str, params: &[(String, String)]) -> Result<Box<dyn Integrator>, ParamError> {
    let e = find(name)?;
    let p = Params::new(e.name, e.params, params)?;
    Ok((e.create)(&p))
}

/// Builds `name` for `scene`: its defaults, then the scene's `<integrator>` properties if
/// the scene names this same estimator (those it does not declare are skipped, with a
/// warning returned), then `params` from the command line.
pub fn create_for_scene(
    name: &str,
    settings: &crate::scene::RenderSettings,
    params: &[(String, String)],
) -> Result<(Box<dyn Integrator>, Vec<String>), ParamError> {
    let (e, p, warnings) = params_for_scene(name, settings, params)?;
    Ok(((e.create)(&p), warnings))
}

/// The estimator and the parameters [`create_for_scene`] builds it from.
pub fn params_for_scene(
    name: &str,
    settings: &crate::scene::RenderSettings,
    params: &[(String, String)],
) -> Result<(&'static Estimator, Params, Vec<String>), ParamError> {
    let e = find(name)?;
    let mut p = Params::new(e.name, e.params, &[])?;
    let mut warnings = Vec::new();
    if e.answers_to(&settings.integrator) {
        for (k, v) in &settings.integrator_params {
            if e.params.iter().any(|s| s.name == k) {
                p.set(k, v)?;
            } else {
                warnings.push(format!("the scene's integrator property '{k}' means nothing to {}; ignored", e.name));
            }
        }
    }
    for (k, v) in params {
        p.set(k, v)?;
    }
    Ok((e, p, warnings))
}

/// Parses an estimator written with its parameters, `name:param=value:param=value` (as
/// `skelight compare --integrators` takes them), into the name and the assignments.
pub fn parse_spec(spec: &str) -> Result<(String, Vec<(String, String)>), ParamError> {
    let mut parts = spec.split(':');
    let name = parts.next().unwrap_or_default().trim().to_string();
    let params = parts.map(params::parse_assignment).collect::<Result<Vec<_>, _>>()?;
    Ok((name, params))
}

/// Builds an estimator by name with its default parameters.
pub fn by_name(name: &str) -> Option<Box<dyn Integrator>> {
    create(name, &[]).ok()
}

/// Every estimator's name.
pub fn names() -> Vec<&'static str> {
    ESTIMATORS.iter().map(|e| e.name).collect()
}

/// A help text listing every estimator and its parameters with their defaults.
pub fn help() -> String {
    let mut s = String::from("Estimators (--integrator NAME, parameters with --param NAME=VALUE):\n");
    for e in ESTIMATORS {
        s += &format!("  {:<8} {}\n", e.name, e.doc);
        for p in e.params {
            s += &format!("           {} = {} ({}): {}\n", p.name, p.default, p.describe_kind(), p.doc);
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_default_parses_and_every_estimator_builds() {
        for e in ESTIMATORS {
            let p = Params::new(e.name, e.params, &[]).unwrap_or_else(|err| panic!("{err}"));
            assert_eq!((e.create)(&p).name(), e.name);
        }
    }

    #[test]
    fn names_and_aliases_are_unique() {
        let mut all: Vec<&str> =
            ESTIMATORS.iter().flat_map(|e| std::iter::once(e.name).chain(e.aliases.iter().copied())).collect();
        let n = all.len();
        all.sort();
        all.dedup();
        assert_eq!(all.len(), n);
    }

    #[test]
    fn unknown_names_list_what_exists() {
        let err = create("nope", &[]).err().unwrap().to_string();
        assert!(err.contains("unknown estimator 'nope'") && err.contains("skelpt"), "{err}");
        assert_eq!(create("path", &[]).unwrap().name(), "pt");
    }

    #[test]
    fn specs_and_scene_properties() {
        let (name, params) = parse_spec("skelpt:strength=16:c_skel=0.25").unwrap();
        assert_eq!((name.as_str(), params.len()), ("skelpt", 2));
        assert!(create(&name, &params).unwrap().describe().contains("strength=16 c_skel=0.25"));
        let mut settings = crate::scene::RenderSettings {
            integrator: "skelpt".into(),
            integrator_params: vec![("strength".into(), "4".into()), ("hide_emitters".into(), "true".into())],
            ..Default::default()
        };
        let (i, warnings) = create_for_scene("skelpt", &settings, &[("c_skel".into(), "0.1".into())]).unwrap();
        assert!(i.describe().contains("strength=4 c_skel=0.1"), "{}", i.describe());
        assert_eq!(warnings.len(), 1);
        // Another estimator's properties are not applied.
        assert!(create_for_scene("pt", &settings, &[]).unwrap().1.is_empty());
        settings.integrator_params = vec![("strength".into(), "-1".into())];
        let err = create_for_scene("skelpt", &settings, &[]).err().unwrap().to_string();
        assert!(err.contains("strength: -1 is outside"), "{err}");
    }
}
