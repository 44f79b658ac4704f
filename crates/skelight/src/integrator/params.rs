//! Typed estimator parameters: what each estimator declares (name, kind, default, range,
//! one line of doc) and the checked values it is built from. One parser serves the command
//! line (`--param name=value`), a scene's `<integrator>` properties and the defaults
//! themselves, so a default that does not parse is caught by a test, not by a user.

use std::fmt;

/// What values a parameter takes.
#[derive(Clone, Copy, Debug)]
pub enum ParamKind {
    /// An integer in `min..=max`.
    Int { min: i64, max: i64 },
    /// A finite real in `min..=max`.
    Float { min: f64, max: f64 },
    /// `true`/`false` (also `1`/`0`, `yes`/`no`, `on`/`off`).
    Bool,
    /// One of these words.
    Choice(&'static [&'static str]),
    /// A file's path (empty: none), read by the estimator when it prepares, which names the
    /// file in its errors.
    Path,
    /// The box an empty-space analysis covers ([`AnalysisBounds::parse`]).
    Bounds,
}

/// One parameter an estimator declares.
#[derive(Clone, Copy, Debug)]
pub struct ParamSpec {
    pub name: &'static str,
    pub kind: ParamKind,
    /// Written as a user would write it; parsed by the same code as their values.
    pub default: &'static str,
    pub doc: &'static str,
}

/// The voxel resolution of the empty-space analysis, as every skeleton-guided estimator
/// takes it.
pub const SKELETON_RESOLUTION: ParamSpec = ParamSpec {
    name: "resolution",
    kind: ParamKind::Int { min: 8, max: 1024 },
    default: "128",
    doc: "voxels on the longest side of the analysed box (see bounds)",
};

/// The box of the scene the empty-space analysis covers, as every skeleton-guided estimator
/// takes it (issue 68 item 5).
pub const SKELETON_BOUNDS: ParamSpec = ParamSpec {
    name: "bounds",
    kind: ParamKind::Bounds,
    default: "occupied",
    doc: "the analysed box: occupied (around the camera and the lights, found by rays; the scene's box where \
          that is most of it), scene (the scene's bounds grown by 10 %), or XMIN;YMIN;ZMIN;XMAX;YMAX;ZMAX",
};

/// The MIS heuristic between bidirectional strategies (`bpt` and the estimators built on it).
pub const MIS_HEURISTIC: ParamSpec = ParamSpec {
    name: "heuristic",
    kind: ParamKind::Choice(&["balance", "power"]),
    default: "balance",
    doc: "MIS heuristic between the (s, t) strategies",
};

/// Which box of the scene the empty-space analysis covers (the `bounds` parameter; the box
/// itself is found in `guided::analysis`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AnalysisBounds {
    /// The space around the camera and the lights ([`occupied_box`]); the scene's box where
    /// that is most of it.
    Occupied,
    /// The scene's bounds grown by 10 % (the thesis').
    Scene,
    /// A box in world units, `[min, max]`.
    Box([[f64; 3]; 2]),
}

impl AnalysisBounds {
    /// `occupied`, `scene`, or six numbers XMIN YMIN ZMIN XMAX YMAX ZMAX separated by
    /// commas, semicolons or spaces (`;` where the value sits in a comma-separated list).
    pub fn parse(text: &str) -> Result<AnalysisBounds, String> {
        match text.trim() {
            "occupied" => return Ok(AnalysisBounds::Occupied),
            "scene" => return Ok(AnalysisBounds::Scene),
            _ => {}
        }
        let v: Vec<f64> = text
            .split(|c: char| c == ',' || c == ';' || c.is_whitespace())
            .filter(|s| !s.is_empty())
            .map(|s| s.parse::<f64>().map_err(|_| format!("'{s}' is not a number")))
            .collect::<Result<_, _>>()?;
        if v.len() != 6 {
            return Err(format!("'{text}' is neither occupied, scene nor six numbers XMIN;YMIN;ZMIN;XMAX;YMAX;ZMAX"));
        }
        if v.iter().any(|x| !x.is_finite()) || (0..3).any(|k| v[k] >= v[k + 3]) {
            return Err(format!("'{text}' is not a box: each minimum must be finite and below its maximum"));
        }
        Ok(AnalysisBounds::Box([[v[0], v[1], v[2]], [v[3], v[4], v[5]]]))
    }
}

/// A checked parameter value.
#[derive(Clone, Debug, PartialEq)]
pub enum ParamValue {
    Int(i64),
    Float(f64),
    Bool(bool),
    Choice(&'static str),
    Text(String),
}

impl fmt::Display for ParamValue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ParamValue::Int(v) => write!(f, "{v}"),
            ParamValue::Float(v) => write!(f, "{v}"),
            ParamValue::Bool(v) => write!(f, "{v}"),
            ParamValue::Choice(v) => write!(f, "{v}"),
            ParamValue::Text(v) => write!(f, "{v}"),
        }
    }
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ParamError {
    #[error("unknown estimator '{name}'; available: {available}")]
    UnknownEstimator { name: String, available: String },
    #[error("{estimator} has no parameter '{name}'; its parameters: {known}")]
    Unknown { estimator: &'static str, name: String, known: String },
    #[error("{estimator}'s parameter {name}: {why}")]
    Invalid { estimator: &'static str, name: &'static str, why: String },
    #[error("'{0}' is not of the form name=value")]
    Syntax(String),
}

impl ParamSpec {
    /// Parses and range-checks `text` for this parameter.
    pub fn parse(&self, text: &str) -> Result<ParamValue, String> {
        let t = text.trim();
        match self.kind {
            ParamKind::Int { min, max } => {
                let v: i64 = t.parse().map_err(|_| format!("'{text}' is not an integer"))?;
                if !(min..=max).contains(&v) {
                    return Err(format!("{v} is outside {min}..={max}"));
                }
                Ok(ParamValue::Int(v))
            }
            ParamKind::Float { min, max } => {
                let v: f64 = t.parse().map_err(|_| format!("'{text}' is not a number"))?;
                if !v.is_finite() || v < min || v > max {
                    return Err(format!("{v} is outside [{min}, {max}]"));
                }
                Ok(ParamValue::Float(v))
            }
            ParamKind::Bool => match t.to_ascii_lowercase().as_str() {
                "true" | "1" | "yes" | "on" => Ok(ParamValue::Bool(true)),
                "false" | "0" | "no" | "off" => Ok(ParamValue::Bool(false)),
                _ => Err(format!("'{text}' is not true or false")),
            },
            ParamKind::Choice(words) => words
                .iter()
                .find(|w| **w == t)
                .map(|w| ParamValue::Choice(w))
                .ok_or_else(|| format!("'{text}' is not one of {}", words.join(", "))),
            ParamKind::Bounds => AnalysisBounds::parse(t).map(|_| ParamValue::Text(t.to_string())),
            ParamKind::Path => {
                if t.contains('\0') {
                    return Err("a path cannot hold a NUL byte".into());
                }
                Ok(ParamValue::Text(t.to_string()))
            }
        }
    }

    /// The range or choices, for help texts.
    pub fn describe_kind(&self) -> String {
        match self.kind {
            ParamKind::Int { min, max } => format!("integer {min}..={max}"),
            ParamKind::Float { min, max } => format!("number in [{min}, {max}]"),
            ParamKind::Bool => "true/false".into(),
            ParamKind::Choice(words) => words.join("|"),
            ParamKind::Path => "a file's path (empty: none)".into(),
            ParamKind::Bounds => "occupied|scene|XMIN;YMIN;ZMIN;XMAX;YMAX;ZMAX".into(),
        }
    }
}

/// Every declared parameter of one estimator with its value: the default unless set.
#[derive(Clone, Debug)]
pub struct Params {
    estimator: &'static str,
    values: Vec<(&'static ParamSpec, ParamValue)>,
}

impl Params {
    /// The defaults of `specs`, then `overrides` in order (a later one wins).
    pub fn new(
        estimator: &'static str,
        specs: &'static [ParamSpec],
        overrides: &[(String, String)],
    ) -> Result<Params, ParamError> {
        let mut values = Vec::with_capacity(specs.len());
        for spec in specs {
            let v = spec.parse(spec.default).map_err(|why| ParamError::Invalid {
                estimator,
                name: spec.name,
                why: format!("its default {why}"),
            })?;
            values.push((spec, v));
        }
        let mut params = Params { estimator, values };
        for (name, text) in overrides {
            params.set(name, text)?;
        }
        Ok(params)
    }

    /// Sets one parameter from text.
    pub fn set(&mut self, name: &str, text: &str) -> Result<(), ParamError> {
        let estimator = self.estimator;
        let known = || self.values.iter().map(|(s, _)| s.name).collect::<Vec<_>>().join(", ");
        let Some(slot) = self.values.iter().position(|(s, _)| s.name == name) else {
            let known = if self.values.is_empty() { "none".to_string() } else { known() };
            return Err(ParamError::Unknown { estimator, name: name.to_string(), known });
        };
        let spec = self.values[slot].0;
        let v = spec.parse(text).map_err(|why| ParamError::Invalid { estimator, name: spec.name, why })?;
        self.values[slot].1 = v;
        Ok(())
    }

    fn get(&self, name: &str) -> &ParamValue {
        // Estimators read only the names they declare: a miss is a programming error.
        &self.values.iter().find(|(s, _)| s.name == name).unwrap_or_else(|| panic!("undeclared parameter {name}")).1
    }

    pub fn int(&self, name: &str) -> i64 {
        match self.get(name) {
            ParamValue::Int(v) => *v,
            other => panic!("parameter {name} is {other:?}, not an integer"),
        }
    }

    pub fn float(&self, name: &str) -> f64 {
        match self.get(name) {
            ParamValue::Float(v) => *v,
            ParamValue::Int(v) => *v as f64,
            other => panic!("parameter {name} is {other:?}, not a number"),
        }
    }

    pub fn bool(&self, name: &str) -> bool {
        match self.get(name) {
            ParamValue::Bool(v) => *v,
            other => panic!("parameter {name} is {other:?}, not a boolean"),
        }
    }

    /// A [`ParamKind::Path`] parameter: `None` when empty.
    pub fn path(&self, name: &str) -> Option<std::path::PathBuf> {
        match self.get(name) {
            ParamValue::Text(v) if v.is_empty() => None,
            ParamValue::Text(v) => Some(std::path::PathBuf::from(v)),
            other => panic!("parameter {name} is {other:?}, not a path"),
        }
    }

    /// A [`ParamKind::Bounds`] parameter (checked when it was parsed).
    pub fn bounds(&self, name: &str) -> AnalysisBounds {
        match self.get(name) {
            ParamValue::Text(v) => AnalysisBounds::parse(v).unwrap_or_else(|e| panic!("parameter {name}: {e}")),
            other => panic!("parameter {name} is {other:?}, not a box"),
        }
    }

    pub fn choice(&self, name: &str) -> &'static str {
        match self.get(name) {
            ParamValue::Choice(v) => v,
            other => panic!("parameter {name} is {other:?}, not a choice"),
        }
    }

    /// The estimator these are the parameters of.
    pub fn estimator(&self) -> &'static str {
        self.estimator
    }

    /// The names of the parameters set to another value than their default: what a device
    /// that honours only some of them (the GPU's kernels) must refuse.
    pub fn changed(&self) -> Vec<&'static str> {
        let default = |s: &ParamSpec| s.parse(s.default).ok();
        self.values.iter().filter(|(s, v)| default(s).as_ref() != Some(v)).map(|(s, _)| s.name).collect()
    }

    /// `name=value` for every parameter, for reports and checkpoint keys.
    pub fn summary(&self) -> String {
        self.values.iter().map(|(s, v)| format!("{}={v}", s.name)).collect::<Vec<_>>().join(" ")
    }
}

/// Splits `name=value`.
pub fn parse_assignment(text: &str) -> Result<(String, String), ParamError> {
    match text.split_once('=') {
        Some((n, v)) if !n.trim().is_empty() => Ok((n.trim().to_string(), v.trim().to_string())),
        _ => Err(ParamError::Syntax(text.to_string())),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    static SPECS: &[ParamSpec] = &[
        ParamSpec { name: "n", kind: ParamKind::Int { min: 1, max: 10 }, default: "4", doc: "" },
        ParamSpec { name: "x", kind: ParamKind::Float { min: 0.0, max: 1.0 }, default: "0.5", doc: "" },
        ParamSpec { name: "on", kind: ParamKind::Bool, default: "false", doc: "" },
        ParamSpec { name: "h", kind: ParamKind::Choice(&["a", "b"]), default: "a", doc: "" },
    ];

    #[test]
    fn defaults_then_overrides() {
        let p = Params::new("t", SPECS, &[("x".into(), "0.25".into()), ("on".into(), "yes".into())]).unwrap();
        assert_eq!((p.int("n"), p.float("x"), p.bool("on"), p.choice("h")), (4, 0.25, true, "a"));
        assert_eq!(p.summary(), "n=4 x=0.25 on=true h=a");
    }

    #[test]
    fn bad_values_name_the_parameter() {
        let bad = |k: &str, v: &str| Params::new("t", SPECS, &[(k.into(), v.into())]).unwrap_err().to_string();
        assert!(bad("n", "11").contains("parameter n: 11 is outside 1..=10"), "{}", bad("n", "11"));
        assert!(bad("x", "NaN").contains("outside"));
        assert!(bad("x", "-0.1").contains("outside [0, 1]"));
        assert!(bad("on", "maybe").contains("not true or false"));
        assert!(bad("h", "c").contains("one of a, b"));
        assert!(bad("zz", "1").contains("no parameter 'zz'; its parameters: n, x, on, h"));
        assert!(parse_assignment("novalue").is_err());
        assert_eq!(parse_assignment(" s = 8 ").unwrap(), ("s".into(), "8".into()));
    }
}
