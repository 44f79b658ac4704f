//! Shards: a render split into deterministic slices of its sample indices, rendered anywhere
//! (other processes, other machines, Dask workers) and merged back into that render.
//!
//! Shard K of N of an S-sample render takes the sample indices ⌊K·S/N⌋ … ⌊(K+1)·S/N⌋ − 1.
//! Every sample draws its random numbers from (seed, pixel, sample index), so a shard's
//! samples are exactly the single render's; a shard keeps its film's f64 sums (not only the
//! image), and merging adds them. The merged image therefore equals the single render up
//! to the order in which f64 sums were added: after rounding to the image's f32, most
//! pixels are bit-identical and the rest differ in the last bit (tested). Estimators that
//! learn from earlier passes ([`crate::integrator::Integrator::learns_across_passes`]:
//! skelbpt, adaptive skelpt) refuse shards: a shard never sees the passes before it.
//!
//! Independent renders (different seeds) merge too ([`merge_independent`]), weighted by
//! their sample counts.
//!
//! A shard's output carries a manifest (which render, which shard, which samples), so that
//! [`merge`] refuses shards of different renders, a shard given twice (a retried shard
//! must not count twice) and a missing one, naming the files.

use std::fmt;
use std::io::{Read, Write};
use std::ops::Range;
use std::path::{Path, PathBuf};

use crate::film::Film;
use crate::imageio::{Annotations, Image, ImageError, ImageOutput};

/// Which slice of a render's samples to take: `index` of `count` (0-based).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Shard {
    pub index: u32,
    pub count: u32,
}

impl Shard {
    /// A shard, checked: 0 ≤ index < count.
    pub fn new(index: u32, count: u32) -> Result<Shard, ShardError> {
        if count == 0 || index >= count {
            return Err(ShardError::Invalid(format!(
                "shard {index}/{count}: the index must be below the count, which must be at least 1"
            )));
        }
        Ok(Shard { index, count })
    }

    /// Parses `K/N`.
    pub fn parse(s: &str) -> Result<Shard, ShardError> {
        let bad = || ShardError::Invalid(format!("'{s}' is not a shard: expected K/N, shard K (from 0) of N"));
        let (k, n) = s.split_once('/').ok_or_else(bad)?;
        Shard::new(k.trim().parse().map_err(|_| bad())?, n.trim().parse().map_err(|_| bad())?)
    }

    /// The sample indices this shard takes of an `spp`-sample render; refuses a split that
    /// would leave a shard empty.
    pub fn samples(&self, spp: u32) -> Result<Range<u32>, ShardError> {
        if spp < self.count {
            return Err(ShardError::Invalid(format!(
                "{} shards of a {spp}-sample render would leave some empty; use at most {spp} shards",
                self.count
            )));
        }
        let at = |k: u32| (k as u64 * spp as u64 / self.count as u64) as u32;
        Ok(at(self.index)..at(self.index + 1))
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

#[derive(Debug, thiserror::Error)]
pub enum ShardError {
    #[error("{0}")]
    Invalid(String),
    #[error("{source_name}: {reason}")]
    Malformed { source_name: String, reason: String },
    #[error(transparent)]
    Image(#[from] ImageError),
    #[error("nothing to merge")]
    Empty,
    #[error("{source_name} is not a shard of {render} but of {other}")]
    OtherRender { source_name: String, render: String, other: String },
    #[error("{first} and {second} are both shard {shard} (a retried shard must be given once)")]
    Duplicate { shard: Shard, first: String, second: String },
    #[error("shards {missing:?} of {count} are missing")]
    Missing { missing: Vec<u32>, count: u32 },
}

/// What a shard's output says about itself (in its EXR header, or its bytes).
#[derive(Clone, Debug, PartialEq)]
pub struct Manifest {
    /// Identifies the render (scene, estimator and parameters, seed, size, depth, total spp).
    pub render: String,
    pub shard: Shard,
    /// The sample indices it took.
    pub samples: Range<u32>,
}

const RENDER: &str = "skelight.render";
const SHARD: &str = "skelight.shard";
const SAMPLES: &str = "skelight.samples";
const FILM: &str = "skelight.film";
const SPP: &str = "skelight.spp";

/// A shard's output: its film (the f64 sums, not only the image) and its manifest.
#[derive(Clone, Debug)]
pub struct ShardOutput {
    pub film: Film,
    pub manifest: Manifest,
}

impl ShardOutput {
    /// Samples per pixel it holds.
    pub fn spp(&self) -> u32 {
        self.manifest.samples.len() as u32
    }

    /// Its header attributes: spp, manifest and the compressed film.
    fn annotations(&self) -> Annotations {
        let m = &self.manifest;
        Annotations {
            numbers: vec![(SPP.into(), self.spp() as f64)],
            texts: vec![
                (RENDER.into(), m.render.clone()),
                (SHARD.into(), m.shard.to_string()),
                (SAMPLES.into(), format!("{}..{}", m.samples.start, m.samples.end)),
            ],
            blobs: vec![(FILM.into(), compress(&self.film.to_bytes()))],
        }
    }

    fn from_annotations(source_name: &str, notes: &Annotations) -> Result<ShardOutput, ShardError> {
        let bad = |reason: String| ShardError::Malformed { source_name: source_name.to_string(), reason };
        let text = |k: &str| notes.text(k).ok_or_else(|| bad(format!("no {k} in its header: not a shard")));
        let render = text(RENDER)?.to_string();
        let shard = Shard::parse(text(SHARD)?).map_err(|e| bad(e.to_string()))?;
        let samples = text(SAMPLES)?;
        let samples = samples
            .split_once("..")
            .and_then(|(a, b)| Some(a.parse::<u32>().ok()?..b.parse::<u32>().ok()?))
            .filter(|r| r.start < r.end)
            .ok_or_else(|| bad(format!("{SAMPLES} = '{samples}' is not a sample range a..b")))?;
        let film = notes.blob(FILM).ok_or_else(|| bad(format!("no {FILM} in its header: not a shard")))?;
        let film = Film::from_bytes(&decompress(film).map_err(bad)?).map_err(bad)?;
        Ok(ShardOutput { film, manifest: Manifest { render, shard, samples } })
    }

    /// Writes the image (viewable like any render) with the manifest and film in its header,
    /// atomically, and a PNG beside it.
    pub fn save(&self, path: &Path, exposure: f32) -> Result<Image, ShardError> {
        let out = ImageOutput::of(path)?;
        let img = self.film.image();
        img.save_exr_annotated(&out.exr, &self.annotations())?;
        img.save_png(&out.png, exposure)?;
        Ok(img)
    }

    pub fn load(path: &Path) -> Result<ShardOutput, ShardError> {
        let (_, notes) = Image::load_exr_annotated(path)?;
        ShardOutput::from_annotations(&path.display().to_string(), &notes)
    }

    /// Self-contained bytes (for Python's pickle and Dask's transfers).
    pub fn to_bytes(&self) -> Vec<u8> {
        let notes = self.annotations();
        let mut out = MAGIC.to_vec();
        for (k, v) in &notes.texts {
            put(&mut out, k.as_bytes());
            put(&mut out, v.as_bytes());
        }
        put(&mut out, &notes.blobs[0].1);
        out
    }

    pub fn from_bytes(source_name: &str, b: &[u8]) -> Result<ShardOutput, ShardError> {
        let bad = |reason: &str| ShardError::Malformed { source_name: source_name.into(), reason: reason.into() };
        let mut rest = b.strip_prefix(MAGIC).ok_or_else(|| bad("not a skelight shard of this version"))?;
        let mut notes = Annotations::default();
        for _ in 0..3 {
            let k = take(&mut rest).ok_or_else(|| bad("truncated"))?;
            let v = take(&mut rest).ok_or_else(|| bad("truncated"))?;
            let text = |b: &[u8]| String::from_utf8(b.to_vec()).map_err(|_| bad("manifest is not text"));
            notes.texts.push((text(k)?, text(v)?));
        }
        let film = take(&mut rest).ok_or_else(|| bad("truncated"))?;
        notes.blobs.push((FILM.into(), film.to_vec()));
        ShardOutput::from_annotations(source_name, &notes)
    }
}

const MAGIC: &[u8; 8] = b"SKLSHRD1";

fn put(out: &mut Vec<u8>, bytes: &[u8]) {
    out.extend_from_slice(&(bytes.len() as u64).to_le_bytes());
    out.extend_from_slice(bytes);
}

fn take<'a>(rest: &mut &'a [u8]) -> Option<&'a [u8]> {
    let n = u64::from_le_bytes(rest.get(..8)?.try_into().ok()?) as usize;
    let v = rest.get(8..8usize.checked_add(n)?)?;
    *rest = &rest[8 + n..];
    Some(v)
}

fn compress(bytes: &[u8]) -> Vec<u8> {
    let mut e = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::fast());
    e.write_all(bytes).expect("writing to memory");
    e.finish().expect("writing to memory")
}

fn decompress(bytes: &[u8]) -> Result<Vec<u8>, String> {
    let mut out = Vec::new();
    flate2::read::ZlibDecoder::new(bytes).read_to_end(&mut out).map_err(|e| format!("film data: {e}"))?;
    Ok(out)
}

/// The merged render: the film of all its samples and their count.
#[derive(Debug)]
pub struct Merged {
    pub film: Film,
    pub spp: u32,
    pub render: String,
    pub shards: u32,
}

/// Merges the shards of one render, each named by where it came from (for errors): refuses
/// shards of different renders, a shard given twice and a missing one, and adds the films
/// in shard order (so the result does not depend on the order they are given or finished).
pub fn merge(parts: Vec<(String, ShardOutput)>) -> Result<Merged, ShardError> {
    let first = parts.first().ok_or(ShardError::Empty)?;
    let (render, count) = (first.1.manifest.render.clone(), first.1.manifest.shard.count);
    let mut slots: Vec<Option<(String, ShardOutput)>> = (0..count).map(|_| None).collect();
    for (name, part) in parts {
        let m = &part.manifest;
        if m.render != render || m.shard.count != count {
            let other = format!("{} ({} shards)", m.render, m.shard.count);
            return Err(ShardError::OtherRender {
                source_name: name,
                render: format!("{render} ({count} shards)"),
                other,
            });
        }
        let slot = &mut slots[m.shard.index as usize];
        if let Some((first, _)) = slot {
            return Err(ShardError::Duplicate { shard: m.shard, first: first.clone(), second: name });
        }
        *slot = Some((name, part));
    }
    let missing: Vec<u32> = (0..count).filter(|&k| slots[k as usize].is_none()).collect();
    if !missing.is_empty() {
        return Err(ShardError::Missing { missing, count });
    }
    // Each shard must hold exactly its slice of the whole render's samples.
    let spp = slots.iter().flatten().map(|(_, p)| p.manifest.samples.end).max().unwrap_or(0);
    for (name, part) in slots.iter().flatten() {
        let expected = part.manifest.shard.samples(spp).map_err(|e| ShardError::Invalid(e.to_string()))?;
        if part.manifest.samples != expected {
            return Err(ShardError::Malformed {
                source_name: name.clone(),
                reason: format!(
                    "shard {} holds samples {:?}, not its slice {expected:?} of {spp}",
                    part.manifest.shard, part.manifest.samples
                ),
            });
        }
    }
    let mut parts = slots.into_iter().flatten();
    let (_, head) = parts.next().expect("count ≥ 1 and none missing");
    let mut spp = head.spp();
    let mut film = head.film;
    let mut end = head.manifest.samples.end;
    for (name, part) in parts {
        if part.manifest.samples.start != end {
            return Err(ShardError::Malformed {
                source_name: name,
                reason: format!(
                    "its samples {:?} do not follow the previous shard's, which end at {end}",
                    part.manifest.samples
                ),
            });
        }
        end = part.manifest.samples.end;
        film.add(&part.film).map_err(|reason| ShardError::Malformed { source_name: name, reason })?;
        spp += part.spp();
    }
    Ok(Merged { film, spp, render, shards: count })
}

/// Loads shard files and merges them (see [`merge`]).
pub fn merge_files(paths: &[PathBuf]) -> Result<Merged, ShardError> {
    let parts = paths
        .iter()
        .map(|p| Ok((p.display().to_string(), ShardOutput::load(p)?)))
        .collect::<Result<Vec<_>, ShardError>>()?;
    merge(parts)
}

/// Merges independent renders of one scene (different seeds) into one image, each weighted
/// by the sample count its header records (`skelight.spp`), or equally with `equal_weights`
/// (for foreign images); returns the image and the total weight. Refuses NaN or infinite
/// pixels, which would spread into every result without a word.
pub fn merge_independent(paths: &[PathBuf], equal_weights: bool) -> Result<(Image, f64), ShardError> {
    let mut loaded = Vec::new();
    for p in paths {
        let bad = |reason: String| ShardError::Malformed { source_name: p.display().to_string(), reason };
        let (img, attrs) = Image::load_exr_with_attributes(p)?;
        if let Some((count, (x, y))) = img.non_finite() {
            return Err(bad(format!(
                "{count} pixels are NaN or infinite (the first at x {x}, y {y}); refusing to merge it"
            )));
        }
        let spp = attrs.iter().find(|(k, _)| k == SPP).map(|a| a.1);
        if let Some(n) = spp.filter(|n| !(*n >= 1.0 && n.fract() == 0.0)) {
            return Err(bad(format!("its header's sample count {SPP} = {n} is not a positive whole number")));
        }
        let n = match (spp, equal_weights) {
            (_, true) => 1.0,
            (Some(n), false) => n,
            (None, false) => {
                return Err(bad(format!(
                    "no sample count ({SPP}) in its header; use --equal-weights for foreign images"
                )))
            }
        };
        loaded.push((img, n));
    }
    let total: f64 = loaded.iter().map(|l| l.1).sum();
    let img = crate::eval::merge_weighted(&loaded).map_err(ShardError::Invalid)?;
    Ok((img, total))
}

/// Whether an EXR is a shard (has a manifest); an error for a file that cannot be read.
pub fn is_shard_file(path: &Path) -> Result<bool, ShardError> {
    Ok(Image::load_exr_annotated(path)?.1.text(SHARD).is_some())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::film::Filter;

    #[test]
    fn shards_cover_the_samples_once() {
        for (spp, n) in [(7u32, 3u32), (16, 4), (5, 5), (1000, 7)] {
            let mut next = 0;
            for k in 0..n {
                let r = Shard::new(k, n).unwrap().samples(spp).unwrap();
                assert_eq!(r.start, next);
                assert!(!r.is_empty());
                next = r.end;
            }
            assert_eq!(next, spp);
        }
        assert!(Shard::new(0, 4).unwrap().samples(3).is_err());
        assert!(Shard::parse("4/4").is_err() && Shard::parse("x").is_err() && Shard::parse("1/0").is_err());
        assert_eq!(Shard::parse(" 2/5").unwrap(), Shard { index: 2, count: 5 });
    }

    fn part(k: u32, n: u32, render: &str) -> (String, ShardOutput) {
        let mut film = Film::new(2, 1, Filter::Box);
        film.splat_paths = k as u64 + 1;
        let shard = Shard::new(k, n).unwrap();
        let samples = shard.samples(8).unwrap();
        (format!("part{k}"), ShardOutput { film, manifest: Manifest { render: render.into(), shard, samples } })
    }

    #[test]
    fn merge_refuses_duplicates_missing_and_foreign_shards() {
        let m = merge(vec![part(2, 3, "a"), part(0, 3, "a"), part(1, 3, "a")]).unwrap();
        assert_eq!((m.spp, m.film.splat_paths), (8, 6));
        let e = merge(vec![part(0, 3, "a"), part(1, 3, "a"), part(1, 3, "a")]).unwrap_err().to_string();
        assert!(e.contains("part1 and part1 are both shard 1/3"), "{e}");
        let e = merge(vec![part(0, 3, "a"), part(2, 3, "a")]).unwrap_err().to_string();
        assert!(e.contains("shards [1] of 3 are missing"), "{e}");
        let e = merge(vec![part(0, 2, "a"), part(1, 2, "b")]).unwrap_err().to_string();
        assert!(e.contains("part1 is not a shard of a"), "{e}");
        let e = merge(vec![part(0, 2, "a"), part(1, 3, "a")]).unwrap_err().to_string();
        assert!(e.contains("not a shard of a (2 shards)"), "{e}");
        let mut odd = part(1, 3, "a");
        odd.1.manifest.samples = 2..6;
        let e = merge(vec![part(0, 3, "a"), odd, part(2, 3, "a")]).unwrap_err().to_string();
        assert!(e.contains("holds samples 2..6, not its slice"), "{e}");
    }

    #[test]
    fn shard_bytes_and_files_round_trip() {
        let (_, p) = part(1, 3, "scene|pt|seed 0");
        let back = ShardOutput::from_bytes("x", &p.to_bytes()).unwrap();
        assert_eq!(back.manifest, p.manifest);
        assert_eq!(back.film.to_bytes(), p.film.to_bytes());
        assert!(ShardOutput::from_bytes("x", &p.to_bytes()[..20]).is_err());
        let dir = std::env::temp_dir().join(format!("skelight-shard-{}", std::process::id()));
        let path = dir.join("s.exr");
        p.save(&path, 0.0).unwrap();
        let back = ShardOutput::load(&path).unwrap();
        assert_eq!(back.manifest, p.manifest);
        assert_eq!(back.film.to_bytes(), p.film.to_bytes());
        assert!(is_shard_file(&path).unwrap());
        Image::new(2, 1).save_exr(&dir.join("plain.exr")).unwrap();
        assert!(!is_shard_file(&dir.join("plain.exr")).unwrap());
        assert!(is_shard_file(&dir.join("missing.exr")).is_err());
        let e = ShardOutput::load(&dir.join("plain.exr")).unwrap_err().to_string();
        assert!(e.contains("plain.exr") && e.contains("not a shard"), "{e}");
        let _ = std::fs::remove_dir_all(dir);
    }
}
