//! The film: reconstruction filters, per-tile accumulation merged in a fixed order (so
//! renders are deterministic whatever the thread count), light-tracing splats, and the
//! per-pixel second moments that statistical tests need.

use crate::color::Rgb;
use crate::imageio::Image;
use crate::math::Vec2;

/// ⌊x⌋ without a call into libm (which baseline x86-64 needs for `f32::floor`); meant for
/// film coordinates (a saturating conversion clamps absurd ones).
#[inline]
fn floor(x: f32) -> i64 {
    let i = x as i64;
    i - i64::from((i as f32) > x)
}

/// Pixel reconstruction filter with Mitsuba's definitions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Filter {
    /// Each sample counts for the pixel it falls in.
    Box,
    /// Triangle of radius `radius` pixels (Mitsuba default 1).
    Tent { radius: f32 },
    /// Truncated Gaussian, radius 4σ, shifted to reach zero there (Mitsuba's).
    Gaussian { stddev: f32 },
}

impl Filter {
    pub fn radius(&self) -> f32 {
        match *self {
            Filter::Box => 0.5,
            Filter::Tent { radius } => radius,
            Filter::Gaussian { stddev } => 4.0 * stddev,
        }
    }
    /// First and last pixel (along one axis) whose centre lies within the filter's reach
    /// of a sample at coordinate `x`.
    #[inline]
    pub fn footprint(&self, x: f32) -> (i64, i64) {
        if *self == Filter::Box {
            // The pixel the sample lies in, [p, p + 1): a sample on an edge counts once.
            let p = floor(x);
            return (p, p);
        }
        let r = self.radius();
        (-floor(-(x - r - 0.5)), floor(x + r - 0.5))
    }
    /// 1D profile at offset `x` pixels.
    #[inline]
    pub fn eval_1d(&self, x: f32) -> f32 {
        self.profile().eval(x)
    }

    /// The pixels a sample at `pos` reaches and their weights, each axis's weights worked
    /// out once per sample rather than once per pixel (a Gaussian's exponentials are most
    /// of a splat's cost otherwise).
    #[inline]
    pub fn footprint_of(&self, pos: Vec2) -> Footprint {
        let (x, y) = (self.footprint(pos.x), self.footprint(pos.y));
        // The box filter weighs every pixel of its footprint 1: no taps to work out.
        let taps = (*self != Filter::Box).then(|| {
            let profile = self.profile();
            (Taps::new(profile, x, pos.x), Taps::new(profile, y, pos.y))
        });
        Footprint { x, y, taps }
    }

    /// For each pixel p of a film `n` pixels wide (along one axis), the integral of the 1D
    /// profile centred on p over the film, ∫₀ⁿ f(x − p − ½) dx. Camera samples spread
    /// uniformly over the film give pixel p this total weight per unit of film area (their
    /// average divides by it); splats divide by it too, so that they estimate the same
    /// filtered pixel value, at the border (where part of the filter falls off the film)
    /// as inside.
    pub fn film_coverage(&self, n: usize) -> Vec<f32> {
        if *self == Filter::Box {
            return vec![1.0; n];
        }
        let profile = self.profile();
        let r = self.radius() as f64;
        // Simpson's rule on each side of the centre, where the profiles are smooth (box and
        // tent: exact; the Gaussian: to ~1e-9 with 64 intervals a side).
        let simpson = |a: f64, b: f64| -> f64 {
            const K: usize = 64;
            if b <= a {
                return 0.0;
            }
            let h = (b - a) / K as f64;
            let f = |x: f64| profile.eval(x as f32) as f64;
            let inner: f64 = (1..K).map(|i| if i % 2 == 1 { 4.0 } else { 2.0 } * f(a + i as f64 * h)).sum();
            (f(a) + inner + f(b)) * h / 3.0
        };
        (0..n)
            .map(|p| {
                let c = p as f64 + 0.5;
                let (lo, hi) = ((-r).max(-c), r.min(n as f64 - c));
                (simpson(lo, 0.0) + simpson(0.0, hi)) as f32
            })
            .collect()
    }

    /// The profile with its per-filter constants worked out.
    #[inline]
    fn profile(&self) -> Profile {
        match *self {
            Filter::Box => Profile::Box,
            Filter::Tent { radius } => Profile::Tent { radius },
            Filter::Gaussian { stddev } => {
                let a = -0.5 / (stddev * stddev);
                let r = 4.0 * stddev;
                Profile::Gaussian { a, floor: (a * r * r).exp() }
            }
        }
    }
}

/// A filter's 1D profile, ready to evaluate.
#[derive(Clone, Copy)]
enum Profile {
    Box,
    Tent {
        radius: f32,
    },
    /// exp(a x²) shifted down by its value at the radius, `floor`.
    Gaussian {
        a: f32,
        floor: f32,
    },
}

impl Profile {
    #[inline]
    fn eval(self, x: f32) -> f32 {
        match self {
            // Half-open, like the box footprint: (−½, ½] around the pixel centre.
            Profile::Box => {
                if x > -0.5 && x <= 0.5 {
                    1.0
                } else {
                    0.0
                }
            }
            Profile::Tent { radius } => (1.0 - x.abs() / radius).max(0.0),
            Profile::Gaussian { a, floor } => ((a * x * x).exp() - floor).max(0.0),
        }
    }
}

/// The pixels a sample reaches, `x.0..=x.1` by `y.0..=y.1`, and its filter's weights
/// there (see [`Filter::footprint_of`]).
pub struct Footprint {
    pub x: (i64, i64),
    pub y: (i64, i64),
    taps: Option<(Taps, Taps)>,
}

impl Footprint {
    /// The weight of pixel (`px`, `py`), inside the footprint.
    #[inline]
    pub fn weight(&self, px: i64, py: i64) -> f32 {
        self.taps.as_ref().map_or(1.0, |(wx, wy)| wx.at(px) * wy.at(py))
    }
}

/// A filter's weights along one axis of a footprint; on the stack unless the footprint is
/// unusually wide.
struct Taps {
    lo: i64,
    inline: [f32; Taps::INLINE],
    spilled: Vec<f32>,
}

impl Taps {
    const INLINE: usize = 8;

    /// The weights of pixels `lo..=hi` for a sample at coordinate `at`.
    #[inline]
    fn new(profile: Profile, (lo, hi): (i64, i64), at: f32) -> Taps {
        let n = (hi - lo + 1).max(0) as usize;
        let mut taps = Taps { lo, inline: [0.0; Taps::INLINE], spilled: Vec::new() };
        let weight = |p: i64| profile.eval(p as f32 + 0.5 - at);
        if n <= Taps::INLINE {
            for (w, p) in taps.inline.iter_mut().zip(lo..=hi) {
                *w = weight(p);
            }
        } else {
            taps.spilled = (lo..=hi).map(weight).collect();
        }
        taps
    }

    #[inline]
    fn at(&self, p: i64) -> f32 {
        let i = (p - self.lo) as usize;
        if self.spilled.is_empty() {
            self.inline[i]
        } else {
            self.spilled[i]
        }
    }
}

/// Accumulates filtered samples for a rectangle of the film (plus the filter's margin).
pub struct FilmTile {
    pub x0: i64,
    pub y0: i64,
    pub width: usize,
    pub height: usize,
    filter: Filter,
    sum: Vec<[f64; 3]>,
    sum_sq: Vec<[f64; 3]>,
    weight: Vec<f64>,
    /// Light-tracing contributions, splatted in order at the merge: one list per band of
    /// [`MERGE_BAND`] film rows the splat's footprint reaches, so that bands merge in
    /// parallel without sorting the splats out first.
    splats: Vec<Vec<(Vec2, Rgb)>>,
    pub rejected: u64,
}

impl FilmTile {
    /// Tile for samples whose positions lie in pixels [x, x+w) × [y, y+h).
    pub fn new(x: usize, y: usize, w: usize, h: usize, filter: Filter) -> FilmTile {
        let m = (filter.radius() - 0.5).ceil().max(0.0) as usize;
        let (width, height) = (w + 2 * m, h + 2 * m);
        FilmTile {
            x0: x as i64 - m as i64,
            y0: y as i64 - m as i64,
            width,
            height,
            filter,
            sum: vec![[0.0; 3]; width * height],
            sum_sq: vec![[0.0; 3]; width * height],
            weight: vec![0.0; width * height],
            splats: Vec::new(),
            rejected: 0,
        }
    }

    /// Adds a camera sample at film position `pos` (pixels). Non-finite values are rejected.
    pub fn add(&mut self, pos: Vec2, l: Rgb) {
        if !l.is_finite() {
            self.rejected += 1;
            return;
        }
        let footprint = self.filter.footprint_of(pos);
        let ((lx, hx), (ly, hy)) = (footprint.x, footprint.y);
        for py in ly..=hy {
            let ty = py - self.y0;
            if ty < 0 || ty >= self.height as i64 {
                continue;
            }
            for px in lx..=hx {
                let tx = px - self.x0;
                if tx < 0 || tx >= self.width as i64 {
                    continue;
                }
                let w = footprint.weight(px, py);
                if w <= 0.0 {
                    continue;
                }
                let i = ty as usize * self.width + tx as usize;
                let v = [l.r as f64, l.g as f64, l.b as f64];
                for (c, vc) in v.iter().enumerate() {
                    self.sum[i][c] += w as f64 * vc;
                    self.sum_sq[i][c] += w as f64 * vc * vc;
                }
                self.weight[i] += w as f64;
            }
        }
    }

    /// Adds a light-tracing contribution anywhere on the film.
    pub fn splat(&mut self, pos: Vec2, l: Rgb) {
        if !l.is_finite() {
            self.rejected += 1;
            return;
        }
        let (ly, hy) = self.filter.footprint(pos.y);
        if hy < 0 || ly >= MAX_FILM_SIDE {
            return; // on no film's rows
        }
        let bands = ly.max(0) as usize / MERGE_BAND..=hy as usize / MERGE_BAND;
        if self.splats.len() <= *bands.end() {
            self.splats.resize_with(bands.end() + 1, Vec::new);
        }
        for band in &mut self.splats[bands] {
            band.push((pos, l));
        }
    }
}

/// Binary film format, version 2: splats divided by each pixel's filter coverage.
const FILM_MAGIC: &[u8; 8] = b"SKLFILM2";

/// The most pixels a film may have along a side.
pub const MAX_FILM_SIDE: i64 = 1 << 16;

/// Film rows merged by one task; tiles sort their splats into bands of this many rows.
const MERGE_BAND: usize = 16;

/// The whole image being accumulated.
#[derive(Clone, Debug)]
pub struct Film {
    pub width: usize,
    pub height: usize,
    pub filter: Filter,
    sum: Vec<[f64; 3]>,
    sum_sq: Vec<[f64; 3]>,
    weight: Vec<f64>,
    splat: Vec<[f64; 3]>,
    /// Number of light paths whose splats `splat` holds (normalises them).
    pub splat_paths: u64,
    pub rejected: u64,
    /// The filter's coverage of each column and row ([`Filter::film_coverage`]).
    coverage: [Vec<f32>; 2],
}

impl Film {
    pub fn new(width: usize, height: usize, filter: Filter) -> Film {
        let n = width * height;
        Film {
            width,
            height,
            filter,
            sum: vec![[0.0; 3]; n],
            sum_sq: vec![[0.0; 3]; n],
            weight: vec![0.0; n],
            splat: vec![[0.0; 3]; n],
            splat_paths: 0,
            rejected: 0,
            coverage: [filter.film_coverage(width), filter.film_coverage(height)],
        }
    }

    pub fn merge_tile(&mut self, tile: &FilmTile) {
        self.merge_tiles(std::slice::from_ref(tile));
    }

    /// Adds the tiles' samples and splats, in the order given, bands of rows in parallel:
    /// every pixel receives its contributions in the same order as a merge one tile at a
    /// time would give it, so the sums are the same to the bit.
    pub fn merge_tiles(&mut self, tiles: &[FilmTile]) {
        use rayon::prelude::*;
        self.rejected += tiles.iter().map(|t| t.rejected).sum::<u64>();
        let (w, filter, n) = (self.width, self.filter, MERGE_BAND * self.width);
        let coverage = &self.coverage;
        if n == 0 {
            return;
        }
        self.sum
            .par_chunks_mut(n)
            .zip(self.sum_sq.par_chunks_mut(n))
            .zip(self.weight.par_chunks_mut(n))
            .zip(self.splat.par_chunks_mut(n))
            .enumerate()
            .for_each(|(b, (((sum, sum_sq), weight), splat))| {
                let mut band = FilmBand { y0: b * MERGE_BAND, width: w, sum, sum_sq, weight, splat, coverage };
                for tile in tiles {
                    band.add_tile(tile);
                }
                for tile in tiles {
                    for &(pos, l) in tile.splats.get(b).into_iter().flatten() {
                        band.add_splat(filter, pos, l);
                    }
                }
            });
    }

    /// Current estimate: filtered camera samples plus splats averaged over light paths.
    pub fn image(&self) -> Image {
        let mut img = Image::new(self.width, self.height);
        let inv_paths = if self.splat_paths > 0 { 1.0 / self.splat_paths as f64 } else { 0.0 };
        for (i, p) in img.pixels.iter_mut().enumerate() {
            let w = self.weight[i];
            let mut v = [0.0f64; 3];
            for (c, vc) in v.iter_mut().enumerate() {
                if w > 0.0 {
                    *vc = self.sum[i][c] / w;
                }
                *vc += self.splat[i][c] * inv_paths;
            }
            *p = Rgb::from_array(v.map(|x| if x.is_finite() { x as f32 } else { 0.0 }));
        }
        img
    }

    /// Per-pixel variance of the pixel estimate (box filter: sample variance / n).
    pub fn variance_image(&self) -> Image {
        let mut img = Image::new(self.width, self.height);
        for (i, p) in img.pixels.iter_mut().enumerate() {
            let w = self.weight[i];
            if w > 1.0 {
                let v = [0, 1, 2].map(|c| {
                    let mean = self.sum[i][c] / w;
                    ((self.sum_sq[i][c] / w - mean * mean).max(0.0) / (w - 1.0)) as f32
                });
                *p = Rgb::from_array(v);
            }
        }
        img
    }

    /// Adds camera samples gathered elsewhere (the GPU's kernels) to pixel `i`: their sum,
    /// sum of squares and total weight, each sample weighted by the film's filter at this
    /// pixel (with the box filter, 1 in its own pixel).
    pub fn add_pixel_samples(&mut self, i: usize, sum: [f64; 3], sum_sq: [f64; 3], count: f64) {
        for c in 0..3 {
            self.sum[i][c] += sum[c];
            self.sum_sq[i][c] += sum_sq[c];
        }
        self.weight[i] += count;
    }

    /// Adds light-tracing contributions gathered elsewhere (the GPU's light pass) to pixel
    /// `i`, each weighted by the film's filter at this pixel (divided here by the filter's
    /// coverage of the pixel, as `splat` is); `splat_paths` is the caller's to count.
    pub fn add_pixel_splats(&mut self, i: usize, sum: [f64; 3]) {
        let (x, y) = (i % self.width, i / self.width);
        let coverage = self.coverage[0][x] as f64 * self.coverage[1][y] as f64;
        for (acc, s) in self.splat[i].iter_mut().zip(sum) {
            *acc += s / coverage;
        }
    }

    /// Adds `other`'s samples and splats to this film (a shard to the merge of the others):
    /// the sums add, so the merge of a render's shards is that render, up to the order in
    /// which the f64 sums were added.
    pub fn add(&mut self, other: &Film) -> Result<(), String> {
        if (self.width, self.height) != (other.width, other.height) {
            return Err(format!("sizes differ: {}×{} vs {}×{}", other.width, other.height, self.width, self.height));
        }
        if self.filter != other.filter {
            return Err(format!("filters differ: {:?} vs {:?}", other.filter, self.filter));
        }
        let add3 = |a: &mut [[f64; 3]], b: &[[f64; 3]]| {
            a.iter_mut().zip(b).for_each(|(a, b)| (0..3).for_each(|c| a[c] += b[c]));
        };
        add3(&mut self.sum, &other.sum);
        add3(&mut self.sum_sq, &other.sum_sq);
        add3(&mut self.splat, &other.splat);
        self.weight.iter_mut().zip(&other.weight).for_each(|(a, b)| *a += b);
        self.splat_paths += other.splat_paths;
        self.rejected += other.rejected;
        Ok(())
    }

    /// Exact binary form (all accumulators as f64), for checkpoints.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(64 + self.weight.len() * 80);
        out.extend_from_slice(FILM_MAGIC);
        let (tag, param) = match self.filter {
            Filter::Box => (0u8, 0.0f32),
            Filter::Tent { radius } => (1, radius),
            Filter::Gaussian { stddev } => (2, stddev),
        };
        for v in [self.width as u64, self.height as u64, self.splat_paths, self.rejected] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.push(tag);
        out.extend_from_slice(&param.to_le_bytes());
        let rgb = |out: &mut Vec<u8>, a: &[[f64; 3]]| {
            a.iter().flatten().for_each(|v| out.extend_from_slice(&v.to_le_bytes()))
        };
        rgb(&mut out, &self.sum);
        rgb(&mut out, &self.sum_sq);
        self.weight.iter().for_each(|v| out.extend_from_slice(&v.to_le_bytes()));
        rgb(&mut out, &self.splat);
        out
    }

    /// Inverse of [`Film::to_bytes`]; refuses truncated or foreign data.
    pub fn from_bytes(b: &[u8]) -> Result<Film, String> {
        let mut pos = 0usize;
        let mut take = |n: usize| -> Result<&[u8], String> {
            let s = b.get(pos..pos + n).ok_or("film data ends early")?;
            pos += n;
            Ok(s)
        };
        if take(8)? != FILM_MAGIC {
            return Err("not a skelight film of this version".into());
        }
        let mut u64s = [0u64; 4];
        for v in &mut u64s {
            *v = u64::from_le_bytes(take(8)?.try_into().unwrap());
        }
        let [w, h, splat_paths, rejected] = u64s;
        let tag = take(1)?[0];
        let param = f32::from_le_bytes(take(4)?.try_into().unwrap());
        let filter = match tag {
            0 => Filter::Box,
            1 => Filter::Tent { radius: param },
            2 => Filter::Gaussian { stddev: param },
            t => return Err(format!("unknown filter tag {t}")),
        };
        let n = (w as usize).checked_mul(h as usize).filter(|&n| n <= 1 << 28).ok_or("film size out of range")?;
        if b.len() < pos + n * 80 {
            return Err("film data ends early".into());
        }
        let mut film = Film::new(w as usize, h as usize, filter);
        film.splat_paths = splat_paths;
        film.rejected = rejected;
        let mut f64s = b[pos..pos + n * 80].chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().unwrap()));
        let fill = |a: &mut Vec<[f64; 3]>, it: &mut dyn Iterator<Item = f64>| {
            for px in a.iter_mut() {
                for v in px.iter_mut() {
                    *v = it.next().unwrap_or(0.0);
                }
            }
        };
        fill(&mut film.sum, &mut f64s);
        fill(&mut film.sum_sq, &mut f64s);
        for v in film.weight.iter_mut() {
            *v = f64s.next().unwrap_or(0.0);
        }
        fill(&mut film.splat, &mut f64s);
        Ok(film)
    }
}

/// Consecutive rows of a film's accumulators, from row `y0` on, merged by one task.
struct FilmBand<'a> {
    y0: usize,
    width: usize,
    sum: &'a mut [[f64; 3]],
    sum_sq: &'a mut [[f64; 3]],
    weight: &'a mut [f64],
    splat: &'a mut [[f64; 3]],
    coverage: &'a [Vec<f32>; 2],
}

impl FilmBand<'_> {
    fn rows(&self) -> std::ops::Range<i64> {
        self.y0 as i64..(self.y0 + self.weight.len() / self.width) as i64
    }

    /// The tile's camera samples on this band's rows.
    fn add_tile(&mut self, tile: &FilmTile) {
        let rows = self.rows();
        // The tile's columns that fall on the film, found once for all its rows.
        let on_film = |x: i64| (x - tile.x0).clamp(0, tile.width as i64) as usize;
        let columns = on_film(0)..on_film(self.width as i64);
        for ty in 0..tile.height {
            let y = tile.y0 + ty as i64;
            if !rows.contains(&y) {
                continue;
            }
            let row = (y - rows.start) as usize * self.width;
            for tx in columns.clone() {
                let (i, j) = (row + (tile.x0 + tx as i64) as usize, ty * tile.width + tx);
                for c in 0..3 {
                    self.sum[i][c] += tile.sum[j][c];
                    self.sum_sq[i][c] += tile.sum_sq[j][c];
                }
                self.weight[i] += tile.weight[j];
            }
        }
    }

    /// The part on this band's rows of a splat of `l` at `pos`, spread by `filter` and
    /// divided by each pixel's coverage, as camera samples are averaged: a pixel's splats
    /// estimate ∫ f(x − p) I(x) dx / ∫_film f(x − p) dx, its filtered value, border pixels
    /// included.
    fn add_splat(&mut self, filter: Filter, pos: Vec2, l: Rgb) {
        let footprint = filter.footprint_of(pos);
        let ((lx, hx), (ly, hy)) = (footprint.x, footprint.y);
        let rows = self.rows();
        let [columns, film_rows] = self.coverage;
        for py in ly.max(rows.start)..=hy.min(rows.end - 1) {
            for px in lx.max(0)..=hx.min(self.width as i64 - 1) {
                let w = footprint.weight(px, py);
                if w <= 0.0 {
                    continue;
                }
                let i = (py - rows.start) as usize * self.width + px as usize;
                let s = w as f64 / (columns[px as usize] as f64 * film_rows[py as usize] as f64);
                self.splat[i][0] += s * l.r as f64;
                self.splat[i][1] += s * l.g as f64;
                self.splat[i][2] += s * l.b as f64;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::vec2;

    #[test]
    fn box_filter_averages_samples_in_their_pixel() {
        let mut film = Film::new(4, 2, Filter::Box);
        let mut tile = FilmTile::new(0, 0, 4, 2, Filter::Box);
        tile.add(vec2(1.2, 0.7), Rgb::splat(2.0));
        tile.add(vec2(1.9, 0.1), Rgb::splat(4.0));
        tile.add(vec2(3.5, 1.5), Rgb::splat(f32::NAN));
        film.merge_tile(&tile);
        let img = film.image();
        assert_eq!(img.get(1, 0).r, 3.0);
        assert_eq!(img.get(0, 0).r, 0.0);
        assert_eq!(film.rejected, 1);
        assert!((film.variance_image().get(1, 0).r - 1.0).abs() < 1e-6);
    }

    #[test]
    fn tent_spreads_into_neighbours_and_tiles_merge_across_borders() {
        let f = Filter::Tent { radius: 1.0 };
        let mut film = Film::new(4, 4, f);
        let mut a = FilmTile::new(0, 0, 2, 4, f);
        a.add(vec2(1.9, 1.5), Rgb::splat(1.0));
        film.merge_tile(&a);
        let img = film.image();
        // The sample near the tile edge reaches pixel 2, which lies in the next tile.
        assert!(img.get(2, 1).r > 0.0 && img.get(1, 1).r > 0.0);
        assert!((f.eval_1d(0.0) - 1.0).abs() < 1e-6 && f.eval_1d(1.0) == 0.0);
        let g = Filter::Gaussian { stddev: 0.5 };
        assert!(g.eval_1d(2.0).abs() < 1e-6 && g.eval_1d(0.0) > g.eval_1d(0.5));
    }

    #[test]
    fn binary_form_round_trips_exactly() {
        let f = Filter::Gaussian { stddev: 0.5 };
        let mut film = Film::new(5, 3, f);
        let mut tile = FilmTile::new(0, 0, 5, 3, f);
        tile.add(vec2(1.3, 2.2), Rgb::splat(0.1));
        tile.splat(vec2(4.5, 0.5), Rgb::splat(7.0));
        film.merge_tile(&tile);
        film.splat_paths = 9;
        let back = Film::from_bytes(&film.to_bytes()).unwrap();
        assert_eq!(back.to_bytes(), film.to_bytes());
        assert_eq!(back.image(), film.image());
        assert!(Film::from_bytes(&film.to_bytes()[..40]).is_err());
    }

    #[test]
    fn splats_are_normalised_by_light_paths() {
        let mut film = Film::new(2, 2, Filter::Box);
        let mut tile = FilmTile::new(0, 0, 2, 2, Filter::Box);
        tile.splat(vec2(0.5, 0.5), Rgb::splat(8.0));
        film.merge_tile(&tile);
        film.splat_paths = 4;
        assert_eq!(film.image().get(0, 0).r, 2.0);
    }

    #[test]
    fn splats_across_merge_bands_merge_the_same_whatever_the_batching() {
        // Gaussian footprints (radius 2) straddle the 16-row merge bands of a 40×50 film.
        let f = Filter::Gaussian { stddev: 0.5 };
        let (w, h) = (40, 50);
        let mut rng = crate::sampling::Rng::new(7, 0, 0);
        let mut tiles = Vec::new();
        for (x0, y0) in [(0, 0), (20, 0), (0, 25), (20, 25)] {
            let mut tile = FilmTile::new(x0, y0, 20, 25, f);
            for _ in 0..200 {
                let pos = vec2(-1.0 + 42.0 * rng.next_f32(), -1.0 + 52.0 * rng.next_f32());
                tile.splat(pos, Rgb::splat(1.0 + rng.next_f32()));
            }
            tile.splat(vec2(-9.0, 1e9), Rgb::splat(5.0)); // on no film
            tiles.push(tile);
        }
        let mut together = Film::new(w, h, f);
        together.merge_tiles(&tiles);
        let mut one_by_one = Film::new(w, h, f);
        for tile in &tiles {
            one_by_one.merge_tile(tile);
        }
        assert_eq!(one_by_one.to_bytes(), together.to_bytes());
    }

    /// Splats and camera samples at the same positions, all of value 1, estimate the same
    /// pixel values for every filter, on the border and in the corners too (where part of
    /// the filter falls off the film: camera samples are averaged over the weight that lands
    /// on it, and splats must be divided by the same).
    #[test]
    fn splats_and_camera_samples_agree_on_every_pixel() {
        for f in
            [Filter::Box, Filter::Tent { radius: 1.0 }, Filter::Tent { radius: 1.7 }, Filter::Gaussian { stddev: 0.5 }]
        {
            let (w, h, k) = (9, 7, 64);
            let mut camera = Film::new(w, h, f);
            let mut tile = FilmTile::new(0, 0, w, h, f);
            // k × k stratified positions per pixel; each splat carries 1/k² of the pixel's
            // area, as a light path's contribution at a film density of k² per pixel would.
            for y in 0..h * k {
                for x in 0..w * k {
                    let pos = vec2((x as f32 + 0.5) / k as f32, (y as f32 + 0.5) / k as f32);
                    tile.add(pos, Rgb::splat(1.0));
                    tile.splat(pos, Rgb::splat(1.0 / (k * k) as f32));
                }
            }
            camera.merge_tile(&tile);
            // The camera average of a constant is exactly 1; remove it to read the splats.
            camera.splat_paths = 1;
            let image = camera.image();
            for y in 0..h {
                for x in 0..w {
                    // Quadrature of the filter by k² points: the error is at most one
                    // point's weight over a row or column of the footprint's edge.
                    let splatted = image.get(x, y).r - 1.0;
                    assert!((splatted - 1.0).abs() < 4e-3, "{f:?} pixel ({x}, {y}): splats give {splatted}, camera 1");
                }
            }
        }
    }

    /// A box-filtered sample on the edge between two pixels (light-tracing positions land
    /// there about W·2⁻²⁴ of the time) counts once, for the pixel it lies in.
    #[test]
    fn box_samples_on_pixel_edges_count_once() {
        let mut film = Film::new(3, 3, Filter::Box);
        let mut tile = FilmTile::new(0, 0, 3, 3, Filter::Box);
        tile.splat(vec2(1.0, 2.0), Rgb::splat(1.0));
        tile.add(vec2(2.0, 1.0), Rgb::splat(1.0));
        film.merge_tile(&tile);
        film.splat_paths = 1;
        let image = film.image();
        let total: f32 = (0..3).flat_map(|y| (0..3).map(move |x| (x, y))).map(|(x, y)| image.get(x, y).r).sum();
        assert_eq!(total, 2.0, "{image:?}");
        assert_eq!((image.get(1, 2).r, image.get(2, 1).r), (1.0, 1.0));
    }

    #[test]
    fn floor_matches_the_standard_library() {
        for x in [-2.5f32, -2.0, -0.5, -0.0, 0.0, 0.3, 1.0, 1.99, 65535.5] {
            assert_eq!(floor(x), x.floor() as i64, "{x}");
        }
    }
}
