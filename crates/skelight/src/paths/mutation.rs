//! Deliberate biases, for measuring what the statistical tests can see (issue 53's power
//! study, `crates/skelight/tests/bias_power.rs`). Every estimator's contribution passes
//! through [`factor`] once per strategy; built without the `mutation` feature that is the
//! constant 1, which the compiler folds away (same image, same bits). With it, a test can
//! scale one strategy's contribution (`2 %/share` of the image, or 0 to measure the share).

/// A sampling strategy, in the (s, t) terms of Veach's thesis (s light vertices, t camera
/// vertices), as the estimators share them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Strategy {
    /// s = 0: a sampled direction finds an emitter or escapes to the environment.
    Hit,
    /// The part of [`Strategy::Hit`] whose last direction was drawn at a vertex the
    /// skeleton guides (`skelpt`'s mixture of its lobes and the BSDF).
    GuidedHit,
    /// s = 1: next-event estimation.
    Nee,
    /// t ≤ 1: a light sub-path joined to the lens, or through the aperture.
    LightTrace,
    /// s, t ≥ 2: two sub-paths joined (resampled joins included).
    Connection,
    /// The joins `skelbpt` and `icbpt` draw from their resampling distributions.
    Resampled,
}

impl Strategy {
    pub const ALL: [Strategy; 6] = [
        Strategy::Hit,
        Strategy::GuidedHit,
        Strategy::Nee,
        Strategy::LightTrace,
        Strategy::Connection,
        Strategy::Resampled,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Strategy::Hit => "hit",
            Strategy::GuidedHit => "guided-hit",
            Strategy::Nee => "nee",
            Strategy::LightTrace => "light-trace",
            Strategy::Connection => "connection",
            Strategy::Resampled => "resampled",
        }
    }
}

#[cfg(not(feature = "mutation"))]
#[inline(always)]
pub fn factor(_: Strategy) -> f32 {
    1.0
}

#[cfg(feature = "mutation")]
static FACTORS: [std::sync::atomic::AtomicU32; 6] = [const { std::sync::atomic::AtomicU32::new(0x3F80_0000) }; 6];

/// The factor a strategy's contribution is multiplied by (1 unless a test set another).
#[cfg(feature = "mutation")]
#[inline]
pub fn factor(s: Strategy) -> f32 {
    f32::from_bits(FACTORS[s as usize].load(std::sync::atomic::Ordering::Relaxed))
}

/// Scales `s`'s contribution by `f` in every render that follows (process-wide).
#[cfg(feature = "mutation")]
pub fn set(s: Strategy, f: f32) {
    FACTORS[s as usize].store(f.to_bits(), std::sync::atomic::Ordering::Relaxed);
}

/// Every strategy back to 1.
#[cfg(feature = "mutation")]
pub fn reset() {
    for s in Strategy::ALL {
        set(s, 1.0);
    }
}
