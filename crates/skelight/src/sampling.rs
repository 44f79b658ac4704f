//! Random numbers, warps from the unit square, and discrete distributions.

use crate::math::{vec2, vec3, Vec2, Vec3, INV_2PI, INV_4PI, INV_PI, PI};

/// 64-bit finaliser (SplitMix64): turns correlated inputs into independent-looking bits.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// PCG32 generator (O'Neill 2014). Streams are selected by hashing, so that any two user
/// seeds, pixels or passes give independent sequences (adjacent seeds are not correlated).
#[derive(Clone, Debug)]
pub struct Rng {
    state: u64,
    inc: u64,
}

impl Rng {
    /// A generator for the `(seed, a, b)` triple, e.g. (user seed, pixel, pass).
    pub fn new(seed: u64, a: u64, b: u64) -> Rng {
        let h1 = mix64(seed ^ mix64(a ^ mix64(b)));
        let h2 = mix64(h1 ^ 0xD1B5_4A32_D192_ED03);
        let mut rng = Rng { state: 0, inc: (h2 << 1) | 1 };
        rng.next_u32();
        rng.state = rng.state.wrapping_add(h1);
        rng.next_u32();
        rng
    }
    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }
    /// Uniform in [0, 1).
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }
    #[inline]
    pub fn next_2d(&mut self) -> Vec2 {
        vec2(self.next_f32(), self.next_f32())
    }
}

/// Cosine-weighted hemisphere around +z (Malley's method on the concentric disk).
#[inline]
pub fn cosine_hemisphere(u: Vec2) -> Vec3 {
    let (d, r2) = concentric_disk_and_radius2(u);
    // From the map's radius rather than from d: the square root then runs beside the
    // division and polynomials of the angle instead of after them.
    let z = (1.0 - r2).max(0.0).sqrt();
    vec3(d.x, d.y, z)
}

#[inline]
pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    cos_theta.max(0.0) * INV_PI
}

/// A cos^n lobe around +z: cosθ = u^(1/(n+1)). Phong's specular lobe, and skelpt's lobe
/// around the skeleton importance direction (thesis eq. 163).
#[inline]
pub fn power_cosine(u: Vec2, exponent: f32) -> Vec3 {
    let cos = u.x.powf(1.0 / (exponent + 1.0));
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    let phi = 2.0 * std::f32::consts::PI * u.y;
    vec3(sin * phi.cos(), sin * phi.sin(), cos)
}

/// [`power_cosine`]'s density, (n+1)/2π · max(0, cos)^n; cos^n by repeated squaring for
/// whole exponents (skelpt evaluates it for every target at every vertex: on veach-door,
/// 160×90, skelpt 0.40–0.43 Msamples/s against 0.35–0.38 with `powf`).
#[inline]
pub fn power_cosine_pdf(cos_theta: f32, exponent: f32) -> f32 {
    power_cosine_norm(exponent) * cos_power(cos_theta, exponent)
}

/// [`power_cosine_pdf`]'s normalisation, (n+1)/2π: a sum of lobes of one exponent takes it
/// once (skelpt's mixture, eq. 167).
#[inline]
pub fn power_cosine_norm(exponent: f32) -> f32 {
    (exponent + 1.0) / (2.0 * std::f32::consts::PI)
}

/// max(0, cos)^n, and 0 for cos ≤ 0 whatever n (0⁰ included).
#[inline]
pub fn cos_power(cos_theta: f32, exponent: f32) -> f32 {
    if cos_theta <= 0.0 {
        0.0
    } else if exponent == exponent.trunc() && (0.0..=1024.0).contains(&exponent) {
        powi_by_squaring(cos_theta, exponent as u32)
    } else {
        cos_theta.powf(exponent)
    }
}

/// x^n by squaring, inlined: `f32::powi` with an exponent known only at run time is a call
/// into compiler-rt's loop (`__powisf2`), which took 8 % of skelpt's time on Sponza.
#[inline]
pub fn powi_by_squaring(x: f32, n: u32) -> f32 {
    let (mut result, mut base, mut n) = (1.0f32, x, n);
    while n > 0 {
        if n & 1 == 1 {
            result *= base;
        }
        base *= base;
        n >>= 1;
    }
    result
}

/// Uniform point on the unit disk (Shirley–Chiu concentric mapping).
#[inline]
pub fn concentric_disk(u: Vec2) -> Vec2 {
    concentric_disk_and_radius2(u).0
}

/// [`concentric_disk`] and the point's squared distance from the centre, known before the
/// point (it is max(a², b²) of the square's coordinates).
#[inline]
fn concentric_disk_and_radius2(u: Vec2) -> (Vec2, f32) {
    let a = 2.0 * u.x - 1.0;
    let b = 2.0 * u.y - 1.0;
    if a == 0.0 && b == 0.0 {
        return (vec2(0.0, 0.0), 0.0);
    }
    // φ = π/4 · b/a, or π/2 − π/4 · a/b whose cosine and sine swap those of π/4 · a/b:
    // both reduce to one angle within ±π/4, where short polynomials are exact to f32.
    let (a2, b2) = (a * a, b * b);
    if a2 > b2 {
        let (sin, cos) = sin_cos_quarter((PI / 4.0) * (b / a));
        (vec2(a * cos, a * sin), a2)
    } else {
        let (sin, cos) = sin_cos_quarter((PI / 4.0) * (a / b));
        (vec2(b * sin, b * cos), b2)
    }
}

/// Sine and cosine of `x` in [−π/4, π/4] (Cephes' single-precision minimax polynomials,
/// within 2 ulp there): a libm call each costs several times as much, and disk and
/// hemisphere sampling never need a wider range.
#[inline]
pub fn sin_cos_quarter(x: f32) -> (f32, f32) {
    let x2 = x * x;
    let sin = x + x * x2 * (-1.666_665_5e-1 + x2 * (8.332_161e-3 + x2 * -1.951_529_6e-4));
    let cos = 1.0 - 0.5 * x2 + x2 * x2 * (4.166_664_6e-2 + x2 * (-1.388_731_6e-3 + x2 * 2.443_315_7e-5));
    (sin, cos)
}

#[inline]
pub fn uniform_sphere(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    vec3(r * phi.cos(), r * phi.sin(), z)
}

pub const UNIFORM_SPHERE_PDF: f32 = INV_4PI;

/// Uniform direction in the cone around +z with the given cosine of the half-angle.
#[inline]
pub fn uniform_cone(u: Vec2, cos_max: f32) -> Vec3 {
    let cos_t = 1.0 - u.x * (1.0 - cos_max);
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    vec3(phi.cos() * sin_t, phi.sin() * sin_t, cos_t)
}

#[inline]
pub fn uniform_cone_pdf(cos_max: f32) -> f32 {
    INV_2PI / (1.0 - cos_max)
}

/// Uniform barycentrics (b1, b2) on a triangle, by Heitz's low-distortion map ("A
/// Low-Distortion Map Between Triangle and Square", 2019): the smaller coordinate is halved
/// and taken from the larger, which needs no square root (emitter sampling runs it per shadow
/// ray).
#[inline]
pub fn uniform_triangle(u: Vec2) -> Vec2 {
    if u.x < u.y {
        let b1 = 0.5 * u.x;
        vec2(b1, u.y - b1)
    } else {
        let b2 = 0.5 * u.y;
        vec2(u.x - b2, b2)
    }
}

/// Balance heuristic for one sample from each of two strategies.
#[inline]
pub fn balance_heuristic(pdf_a: f32, pdf_b: f32) -> f32 {
    if pdf_a + pdf_b > 0.0 {
        pdf_a / (pdf_a + pdf_b)
    } else {
        0.0
    }
}

/// Power heuristic (β = 2) for one sample from each of two strategies.
#[inline]
pub fn power_heuristic(pdf_a: f32, pdf_b: f32) -> f32 {
    let a = pdf_a * pdf_a;
    let b = pdf_b * pdf_b;
    if a + b > 0.0 && a.is_finite() {
        a / (a + b)
    } else if a.is_infinite() {
        1.0
    } else {
        0.0
    }
}

/// [`power_heuristic`]`(pdf_a, pdf_b) / pdf_a`, what a sample from strategy a is scaled by,
/// with one division instead of two. Zero where the sum of squares is zero or overflows (the
/// weight over the density is then negligible).
#[inline]
pub fn power_heuristic_over_pdf(pdf_a: f32, pdf_b: f32) -> f32 {
    let sum = pdf_a * pdf_a + pdf_b * pdf_b;
    if sum > 0.0 && sum.is_finite() {
        pdf_a / sum
    } else {
        0.0
    }
}

/// Piecewise-constant 1D distribution over `n` bins, sampled by inverting its CDF.
#[derive(Clone, Debug)]
pub struct Distribution1D {
    pub func: Vec<f32>,
    cdf: Vec<f32>,
    integral: f32,
}

impl Distribution1D {
    /// Negative or non-finite weights count as zero; an all-zero input becomes uniform.
    pub fn new(weights: &[f32]) -> Distribution1D {
        let n = weights.len().max(1);
        let mut func: Vec<f32> = weights.iter().map(|&w| if w.is_finite() && w > 0.0 { w } else { 0.0 }).collect();
        if func.is_empty() {
            func.push(0.0);
        }
        let mut cdf = Vec::with_capacity(n + 1);
        cdf.push(0.0f32);
        let mut acc = 0.0f64;
        for &f in &func {
            acc += f as f64;
            cdf.push(acc as f32);
        }
        let mut integral = acc as f32;
        if !(integral > 0.0) {
            func.iter_mut().for_each(|f| *f = 1.0);
            for (i, c) in cdf.iter_mut().enumerate() {
                *c = i as f32;
            }
            integral = n as f32;
        }
        for c in cdf.iter_mut() {
            *c /= integral;
        }
        cdf[n] = 1.0;
        Distribution1D { func, cdf, integral }
    }
    pub fn len(&self) -> usize {
        self.func.len()
    }
    pub fn is_empty(&self) -> bool {
        self.func.is_empty()
    }
    /// The cumulative table: n + 1 values from 0 to 1 (for kernels that search it themselves).
    pub fn cdf(&self) -> &[f32] {
        &self.cdf
    }
    /// Sum of the weights.
    pub fn integral(&self) -> f32 {
        self.integral
    }
    /// Probability of bin `i`.
    #[inline]
    pub fn pmf(&self, i: usize) -> f32 {
        self.func[i] / self.integral
    }
    /// Picks a bin; returns (index, probability, `u` remapped to [0,1) inside the bin).
    #[inline]
    pub fn sample_discrete(&self, u: f32) -> (usize, f32, f32) {
        let n = self.func.len();
        if n == 1 {
            // A single light or triangle, common enough to skip the search (same result).
            return (0, 1.0, u.clamp(0.0, 0.999_999_94));
        }
        // Largest i with cdf[i] <= u.
        let i = (self.cdf.partition_point(|&c| c <= u).saturating_sub(1)).min(n - 1);
        let mut i = i;
        while self.func[i] == 0.0 && i + 1 < n {
            i += 1;
        }
        while self.func[i] == 0.0 && i > 0 {
            i -= 1;
        }
        let width = self.cdf[i + 1] - self.cdf[i];
        let rem = if width > 0.0 { ((u - self.cdf[i]) / width).clamp(0.0, 0.999_999_94) } else { 0.5 };
        (i, self.pmf(i), rem)
    }
}

/// Piecewise-constant 2D distribution on [0, 1]² (rows = v, columns = u).
#[derive(Clone, Debug)]
pub struct Distribution2D {
    conditional: Vec<Distribution1D>,
    marginal: Distribution1D,
    width: usize,
    height: usize,
}

impl Distribution2D {
    pub fn new(weights: &[f32], width: usize, height: usize) -> Distribution2D {
        let conditional: Vec<Distribution1D> =
            (0..height).map(|y| Distribution1D::new(&weights[y * width..(y + 1) * width])).collect();
        let row_sums: Vec<f32> = (0..height)
            .map(|y| weights[y * width..(y + 1) * width].iter().filter(|w| w.is_finite() && **w > 0.0).sum())
            .collect();
        Distribution2D { conditional, marginal: Distribution1D::new(&row_sums), width, height }
    }
    /// The distribution over rows, and each row's over its columns.
    pub fn marginal(&self) -> &Distribution1D {
        &self.marginal
    }
    pub fn conditionals(&self) -> &[Distribution1D] {
        &self.conditional
    }
    /// Returns the point in [0, 1]² and its density with respect to area on [0, 1]².
    pub fn sample(&self, u: Vec2) -> (Vec2, f32) {
        let (row, p_row, v_rem) = self.marginal.sample_discrete(u.y);
        let (col, p_col, u_rem) = self.conditional[row].sample_discrete(u.x);
        let p = vec2((col as f32 + u_rem) / self.width as f32, (row as f32 + v_rem) / self.height as f32);
        (p, p_row * p_col * (self.width * self.height) as f32)
    }
    /// Density at a point of [0, 1]².
    pub fn pdf(&self, p: Vec2) -> f32 {
        let col = ((p.x * self.width as f32) as usize).min(self.width - 1);
        let row = ((p.y * self.height as f32) as usize).min(self.height - 1);
        self.marginal.pmf(row) * self.conditional[row].pmf(col) * (self.width * self.height) as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quarter_sine_and_cosine_match_libm() {
        let mut worst = 0.0f32;
        for i in -100_000..=100_000 {
            let x = (PI / 4.0) * i as f32 / 100_000.0;
            let (sin, cos) = sin_cos_quarter(x);
            let (s64, c64) = (x as f64).sin_cos();
            worst = worst.max((sin as f64 - s64).abs() as f32).max((cos as f64 - c64).abs() as f32);
        }
        // Two units in the last place of values up to 1.
        assert!(worst <= 2.0 * f32::EPSILON, "worst error {worst:e}");
    }

    #[test]
    fn adjacent_seeds_are_uncorrelated() {
        let n = 20000;
        let mut a = Rng::new(1001, 0, 0);
        let mut b = Rng::new(1002, 0, 0);
        let (mut sab, mut sa, mut sb, mut saa, mut sbb) = (0.0f64, 0.0, 0.0, 0.0, 0.0);
        for _ in 0..n {
            let x = a.next_f32() as f64;
            let y = b.next_f32() as f64;
            sab += x * y;
            sa += x;
            sb += y;
            saa += x * x;
            sbb += y * y;
        }
        let nf = n as f64;
        let cov = sab / nf - sa * sb / nf / nf;
        let corr = cov / ((saa / nf - (sa / nf).powi(2)) * (sbb / nf - (sb / nf).powi(2))).sqrt();
        // Standard error of a correlation estimate is 1/sqrt(n) ≈ 0.007; allow 5 of them.
        assert!(corr.abs() < 5.0 / nf.sqrt(), "correlation {corr}");
        assert!((sa / nf - 0.5).abs() < 0.01);
    }

    #[test]
    fn distribution_1d_samples_in_proportion() {
        let d = Distribution1D::new(&[1.0, 0.0, 3.0]);
        let mut rng = Rng::new(7, 0, 0);
        let mut counts = [0usize; 3];
        let n = 40000;
        for _ in 0..n {
            let (i, p, rem) = d.sample_discrete(rng.next_f32());
            assert!((0.0..1.0).contains(&rem));
            assert!((p - d.pmf(i)).abs() < 1e-6);
            counts[i] += 1;
        }
        assert_eq!(counts[1], 0);
        let f = counts[2] as f64 / n as f64;
        // Binomial standard error sqrt(p(1-p)/n) ≈ 0.0022; 5 sigma.
        assert!((f - 0.75).abs() < 0.011, "{f}");
    }

    #[test]
    fn distribution_2d_pdf_matches_sampling() {
        let w = [1.0, 2.0, 0.0, 4.0, 0.5, 0.5];
        let d = Distribution2D::new(&w, 3, 2);
        let mut rng = Rng::new(3, 0, 0);
        for _ in 0..1000 {
            let (p, pdf) = d.sample(rng.next_2d());
            assert!((d.pdf(p) - pdf).abs() < 1e-3 * pdf.max(1.0), "{p:?}");
        }
        // Density integrates to 1: sum over cells of pdf * cell area.
        let total: f32 = (0..2)
            .flat_map(|y| (0..3).map(move |x| (x, y)))
            .map(|(x, y)| d.pdf(vec2((x as f32 + 0.5) / 3.0, (y as f32 + 0.5) / 2.0)) / 6.0)
            .sum();
        assert!((total - 1.0).abs() < 1e-4);
    }

    /// The fused form agrees with the power heuristic's weight divided by the density.
    #[test]
    fn power_heuristic_over_pdf_is_the_weight_over_the_density() {
        let mut rng = Rng::new(9, 0, 0);
        for _ in 0..100_000 {
            // Densities over twelve decades, as solid-angle densities span.
            let (a, b) = (10f32.powf(12.0 * rng.next_f32() - 6.0), 10f32.powf(12.0 * rng.next_f32() - 6.0));
            let (fused, two_steps) = (power_heuristic_over_pdf(a, b), power_heuristic(a, b) / a);
            // Four roundings (two squares, a sum, a division) against five (the same and a
            // second division), each within ε/2: apart by at most 4.5 ε (observed 1.5 ε).
            assert!((fused - two_steps).abs() <= 4.5 * f32::EPSILON * two_steps, "{a} {b}: {fused} vs {two_steps}");
        }
        assert_eq!(power_heuristic_over_pdf(0.0, 0.0), 0.0);
        assert_eq!(power_heuristic_over_pdf(1e-30, 1e-30), 0.0);
        assert_eq!(power_heuristic_over_pdf(1e30, 1.0), 0.0);
    }

    /// One bin (a scene's only light, a light's only triangle): the sample itself, as the
    /// search would give it for a two-bin distribution whose second bin is empty.
    #[test]
    fn single_bin_passes_the_sample_through() {
        let (one, two) = (Distribution1D::new(&[3.0]), Distribution1D::new(&[3.0, 0.0]));
        for u in [0.0, 0.25, 0.5, 0.999, 1.0] {
            assert_eq!(one.sample_discrete(u), two.sample_discrete(u), "u = {u}");
        }
    }

    /// χ² of triangle samples over a grid in (b1, b2): cells inside the triangle expect
    /// their area, cells cut by the diagonal half of it.
    #[test]
    fn triangle_samples_are_uniform() {
        const N: usize = 16;
        const SAMPLES: usize = 400_000;
        let mut counts = [[0u32; N]; N];
        let mut rng = Rng::new(5, 0, 0);
        for _ in 0..SAMPLES {
            let b = uniform_triangle(rng.next_2d());
            let (i, j) = (((b.x * N as f32) as usize).min(N - 1), ((b.y * N as f32) as usize).min(N - 1));
            assert!(i + j < N, "{b:?} outside the triangle");
            counts[i][j] += 1;
        }
        let (mut chi2, mut cells) = (0.0f64, 0);
        for (i, row) in counts.iter().enumerate() {
            for (j, &c) in row.iter().enumerate().take(N - i) {
                let area = if i + j + 1 == N { 0.5 } else { 1.0 };
                let expected = SAMPLES as f64 * area / (N * N) as f64 * 2.0;
                chi2 += (c as f64 - expected).powi(2) / expected;
                cells += 1;
            }
        }
        // 136 cells, 135 degrees of freedom: mean 135, sd 16.4; 6 sd above the mean.
        assert!(chi2 < (cells - 1) as f64 + 6.0 * (2.0 * (cells - 1) as f64).sqrt(), "chi2 {chi2} over {cells} cells");
    }

    #[test]
    fn warps_stay_on_their_domains() {
        let mut rng = Rng::new(11, 0, 0);
        for _ in 0..100_000 {
            let u = rng.next_2d();
            let d = cosine_hemisphere(u);
            assert!(d.z >= 0.0 && (d.length() - 1.0).abs() < 1e-4);
            assert!((uniform_sphere(u).length() - 1.0).abs() < 1e-4);
            let b = uniform_triangle(u);
            assert!(b.x >= 0.0 && b.y >= 0.0 && b.x + b.y <= 1.0 + 1e-6);
            // The disk mapping keeps each coordinate's sign where it is not tiny.
            let d = concentric_disk(u);
            assert!(d.x * d.x + d.y * d.y <= 1.0 + 4.0 * f32::EPSILON);
            let (a, b) = (2.0 * u.x - 1.0, 2.0 * u.y - 1.0);
            if a.abs() > 1e-3 && b.abs() > 1e-3 {
                assert_eq!((d.x > 0.0, d.y > 0.0), (a > 0.0, b > 0.0), "u = {u:?} gave {d:?}");
            }
        }
    }
}
