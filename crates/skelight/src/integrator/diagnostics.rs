//! What an estimator shows of itself for `render --debug DIR` (and Python's `debug=`): the
//! parts its image splits into, and pictures of its internals. Each estimator owns its own
//! (bpt's strategies, skelpt's importance views, the resampling estimators' distributions
//! and nodes); the CLI and Python write whatever an estimator offers, knowing none of them.

use super::Integrator;
use crate::imageio::Image;

/// The parts an estimator's image splits into: variants of it, each recording one part,
/// rendered with the same seed and sample count so that the parts add up to the full image
/// (thesis Fig. 106 for the resampling estimators; one (s, t) strategy each for bpt).
pub struct DebugParts {
    /// The CSV of the parts' means: its file name and the header of its leading columns.
    pub table: (&'static str, &'static str),
    pub parts: Vec<DebugPart>,
}

/// One part: its file stem, its CSV columns and the estimator recording only it.
pub struct DebugPart {
    pub stem: String,
    pub columns: String,
    pub estimator: Box<dyn Integrator>,
}

/// A file an estimator writes of its internals once prepared and rendered.
pub enum DebugFile {
    /// A picture, written as PNG (no exposure).
    Png { name: String, image: Image },
    /// A text file (JSON).
    Text { name: String, text: String },
}

impl DebugFile {
    pub fn name(&self) -> &str {
        match self {
            DebugFile::Png { name, .. } | DebugFile::Text { name, .. } => name,
        }
    }
}
