//! Checkpoints of long renders: the accumulated film, the number of samples per pixel done
//! and the wall time spent. Random numbers are a function of (seed, pixel, sample index),
//! so the sample count *is* the generator state: resuming continues the same sequence and
//! a resumed render equals an uninterrupted one bit for bit.

use std::path::Path;
use std::time::Duration;

use crate::film::Film;
use crate::imageio::write_atomically;

pub struct Checkpoint {
    /// What the render is of (scene, estimator, seed, resolution): a resume must match it.
    pub key: String,
    pub spp: u32,
    pub elapsed: Duration,
    pub film: Film,
}

/// Version 2: splats normalised by the filter's coverage of each pixel, and scenes with
/// Mitsuba's default near clip; a version-1 checkpoint holds a different image.
const MAGIC: &[u8; 8] = b"SKLCKPT2";

impl Checkpoint {
    /// Writes atomically: a crash leaves the previous checkpoint intact.
    pub fn save(&self, path: &Path) -> Result<(), String> {
        let mut out = Vec::new();
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&(self.key.len() as u64).to_le_bytes());
        out.extend_from_slice(self.key.as_bytes());
        out.extend_from_slice(&self.spp.to_le_bytes());
        out.extend_from_slice(&self.elapsed.as_secs_f64().to_le_bytes());
        out.extend_from_slice(&self.film.to_bytes());
        write_atomically(path, |tmp| std::fs::write(tmp, &out).map_err(|e| e.to_string()))
    }

    pub fn load(path: &Path) -> Result<Checkpoint, String> {
        let b = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let bad = |m: &str| format!("{}: not a usable checkpoint ({m})", path.display());
        if b.len() < 16 || &b[..8] != MAGIC {
            return Err(bad("not a checkpoint of this skelight version; remove it to start afresh"));
        }
        let klen = u64::from_le_bytes(b[8..16].try_into().unwrap()) as usize;
        let rest = b.get(16..).ok_or_else(|| bad("truncated"))?;
        if rest.len() < klen.saturating_add(12) {
            return Err(bad("truncated"));
        }
        let key = String::from_utf8(rest[..klen].to_vec()).map_err(|_| bad("key is not text"))?;
        let spp = u32::from_le_bytes(rest[klen..klen + 4].try_into().unwrap());
        let secs = f64::from_le_bytes(rest[klen + 4..klen + 12].try_into().unwrap());
        let film = Film::from_bytes(&rest[klen + 12..]).map_err(|e| bad(&e))?;
        if !(secs >= 0.0 && secs.is_finite()) {
            return Err(bad("bad elapsed time"));
        }
        Ok(Checkpoint { key, spp, elapsed: Duration::from_secs_f64(secs), film })
    }
}
