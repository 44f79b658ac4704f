//! Image error metrics (per channel with the seeds' max over RGB, and on luminance) and the
//! block-mean statistic used to test estimators against references.

use crate::color::Rgb;
use crate::imageio::Image;

/// Errors of an image against a reference.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Metrics {
    /// Mean absolute error, max over RGB channels.
    pub mae: f64,
    /// Root mean squared error, max over RGB.
    pub rmse: f64,
    /// Mean of (x−r)²/(r²+ε), max over RGB.
    pub relmse: f64,
    /// RMSE divided by the reference's mean, max over RGB.
    pub nrmse: f64,
    /// The same four on luminance.
    pub mae_lum: f64,
    pub rmse_lum: f64,
    pub relmse_lum: f64,
    pub nrmse_lum: f64,
}

/// ε in relMSE's denominator, as in the literature (avoids division by black pixels).
pub const RELMSE_EPSILON: f64 = 1e-2;

#[derive(Debug, thiserror::Error)]
#[error("images differ in size: {0}×{1} vs {2}×{3}")]
pub struct SizeMismatch(usize, usize, usize, usize);

fn channel_stats(img: &Image, reference: &Image, f: impl Fn(Rgb) -> [f64; 4]) -> [[f64; 4]; 4] {
    // For each of up to 4 channels: sum |d|, sum d², sum d²/(r²+ε), sum r.
    let mut acc = [[0.0f64; 4]; 4];
    for (a, r) in img.pixels.iter().zip(&reference.pixels) {
        let (va, vr) = (f(*a), f(*r));
        for c in 0..4 {
            let d = va[c] - vr[c];
            acc[c][0] += d.abs();
            acc[c][1] += d * d;
            acc[c][2] += d * d / (vr[c] * vr[c] + RELMSE_EPSILON);
            acc[c][3] += vr[c];
        }
    }
    acc
}

pub fn metrics(img: &Image, reference: &Image) -> Result<Metrics, SizeMismatch> {
    if img.width != reference.width || img.height != reference.height {
        return Err(SizeMismatch(img.width, img.height, reference.width, reference.height));
    }
    let n = img.pixels.len().max(1) as f64;
    let acc = channel_stats(img, reference, |p| [p.r as f64, p.g as f64, p.b as f64, p.luminance() as f64]);
    let per = |c: usize| {
        let mae = acc[c][0] / n;
        let rmse = (acc[c][1] / n).sqrt();
        let relmse = acc[c][2] / n;
        let mean = acc[c][3] / n;
        // A channel that is black in the reference has no relative error unless it is wrong.
        let nrmse = if mean > 0.0 {
            rmse / mean
        } else if rmse == 0.0 {
            0.0
        } else {
            f64::INFINITY
        };
        [mae, rmse, relmse, nrmse]
    };
    let rgb = [per(0), per(1), per(2)];
    let max = |k: usize| rgb.iter().map(|m| m[k]).fold(0.0f64, f64::max);
    let lum = per(3);
    Ok(Metrics {
        mae: max(0),
        rmse: max(1),
        relmse: max(2),
        nrmse: max(3),
        mae_lum: lum[0],
        rmse_lum: lum[1],
        relmse_lum: lum[2],
        nrmse_lum: lum[3],
    })
}

/// Means of `block`×`block` pixel blocks, per channel (row-major blocks).
pub fn block_means(img: &Image, block: usize) -> Vec<[f64; 3]> {
    let (bw, bh) = (img.width / block, img.height / block);
    let mut out = vec![[0.0f64; 3]; bw * bh];
    for by in 0..bh {
        for bx in 0..bw {
            let mut s = [0.0f64; 3];
            for y in by * block..(by + 1) * block {
                for x in bx * block..(bx + 1) * block {
                    let p = img.get(x, y);
                    s[0] += p.r as f64;
                    s[1] += p.g as f64;
                    s[2] += p.b as f64;
                }
            }
            out[by * bw + bx] = s.map(|v| v / (block * block) as f64);
        }
    }
    out
}

/// The conformance statistic: with two independent renders r1, r2 and a reference,
/// T = mean_b (avg_b − ref_b)² / mean_b ((r1_b − r2_b)²/4) over block means and channels.
/// For an unbiased estimator T ≈ 1 at any sample count; bias inflates it.
pub fn block_t_statistic(r1: &Image, r2: &Image, reference: &Image, block: usize) -> f64 {
    weighted_t(r1, r2, reference, None, block, |_, _| 1.0)
}

/// [`block_t_statistic`] on relative errors: each block and channel is weighted by
/// 1/(ref² + ε²), ε = 1 % of the channel's mean. The weights depend on the reference only,
/// so T ≈ 1 still holds without bias, while a few very bright blocks (a visible light's
/// edges) no longer dominate both sums and leave the statistic with a handful of terms.
/// (Weights from the renders' own variance would favour blocks that missed a rare, bright
/// path and bias the numerator when the noise is heavy-tailed, as with caustics.)
///
/// `reference_variance`, the per-pixel variance of the reference itself, adds the
/// reference's own noise to the denominator: an estimator far less noisy than the one that
/// made the reference (light tracing on a caustic a path tracer rendered) would otherwise
/// measure the reference's noise as its bias.
pub fn relative_block_t_statistic(
    r1: &Image,
    r2: &Image,
    reference: &Image,
    reference_variance: Option<&Image>,
    block: usize,
) -> f64 {
    let r = block_means(reference, block);
    let nb = r.len().max(1) as f64;
    let eps2: [f64; 3] = [0, 1, 2].map(|c| (0.01 * r.iter().map(|x| x[c].abs()).sum::<f64>() / nb).powi(2) + 1e-30);
    let block_var = reference_variance.map(|v| {
        // Variance of a block mean: the sum of its pixels' variances over block⁴.
        block_means(v, block).into_iter().map(|m| m.map(|x| x / (block * block) as f64)).collect::<Vec<_>>()
    });
    weighted_t(r1, r2, reference, block_var.as_deref(), block, |reference, c| 1.0 / (reference * reference + eps2[c]))
}

/// T with a weight per block and channel, given the reference block mean and the channel.
fn weighted_t(
    r1: &Image,
    r2: &Image,
    reference: &Image,
    reference_block_var: Option<&[[f64; 3]]>,
    block: usize,
    weight: impl Fn(f64, usize) -> f64,
) -> f64 {
    let (a, b, r) = (block_means(r1, block), block_means(r2, block), block_means(reference, block));
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for i in 0..r.len() {
        for c in 0..3 {
            let w = weight(r[i][c], c);
            num += w * (0.5 * (a[i][c] + b[i][c]) - r[i][c]).powi(2);
            den += w * (a[i][c] - b[i][c]).powi(2) / 4.0;
            if let Some(v) = reference_block_var {
                den += w * v[i][c];
            }
        }
    }
    if den > 0.0 {
        num / den
    } else if num > 0.0 {
        f64::INFINITY
    } else {
        1.0
    }
}

/// Combines independent estimates of one image, each weighted by its sample count:
/// Σ nᵢ·imageᵢ / Σ nᵢ (the estimate a single render of Σ nᵢ samples would give).
pub fn merge_weighted(parts: &[(Image, f64)]) -> Result<Image, String> {
    let (first, _) = parts.first().ok_or("nothing to merge")?;
    let total: f64 = parts.iter().map(|p| p.1).sum();
    if !(total > 0.0) || parts.iter().any(|p| !(p.1 >= 0.0)) {
        return Err("sample counts must be positive".into());
    }
    let mut acc = vec![[0.0f64; 3]; first.pixels.len()];
    for (img, n) in parts {
        if (img.width, img.height) != (first.width, first.height) {
            return Err(format!("sizes differ: {}×{} vs {}×{}", img.width, img.height, first.width, first.height));
        }
        for (a, p) in acc.iter_mut().zip(&img.pixels) {
            for (c, v) in p.to_array().iter().enumerate() {
                a[c] += n * *v as f64;
            }
        }
    }
    let pixels = acc.iter().map(|a| Rgb::from_array(a.map(|v| (v / total) as f32))).collect();
    Ok(Image { width: first.width, height: first.height, pixels })
}

/// False-colour relative error |a−r|/(r+ε) on luminance, ε = 1 % of the reference mean:
/// black (0) through blue, green, yellow to red (≥ `max`).
pub fn error_image(img: &Image, reference: &Image, max: f32) -> Result<Image, SizeMismatch> {
    if img.width != reference.width || img.height != reference.height {
        return Err(SizeMismatch(img.width, img.height, reference.width, reference.height));
    }
    let eps = 0.01 * reference.mean().luminance().max(1e-6);
    let ramp = [
        Rgb::BLACK,
        Rgb::from_array([0.0, 0.0, 1.0]),
        Rgb::from_array([0.0, 1.0, 0.0]),
        Rgb::from_array([1.0, 1.0, 0.0]),
        Rgb::from_array([1.0, 0.0, 0.0]),
    ];
    let pixels = img
        .pixels
        .iter()
        .zip(&reference.pixels)
        .map(|(a, r)| {
            let e = (a.luminance() - r.luminance()).abs() / (r.luminance().abs() + eps);
            let x = if e.is_finite() {
                (e / max).clamp(0.0, 1.0) * (ramp.len() - 1) as f32
            } else {
                (ramp.len() - 1) as f32
            };
            let i = (x as usize).min(ramp.len() - 2);
            let f = x - i as f32;
            ramp[i] * (1.0 - f) + ramp[i + 1] * f
        })
        .collect();
    Ok(Image { width: img.width, height: img.height, pixels })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::color::rgb;

    #[test]
    fn metrics_match_hand_computed_values() {
        let reference = Image { width: 2, height: 1, pixels: vec![rgb(1.0, 2.0, 0.0), rgb(3.0, 2.0, 0.0)] };
        let img = Image { width: 2, height: 1, pixels: vec![rgb(2.0, 2.0, 0.0), rgb(1.0, 2.0, 0.0)] };
        let m = metrics(&img, &reference).unwrap();
        // Red errors: +1 and −2 → MAE 1.5, RMSE sqrt(2.5); other channels exact.
        assert!((m.mae - 1.5).abs() < 1e-12);
        assert!((m.rmse - 2.5f64.sqrt()).abs() < 1e-12);
        // relMSE red: (1/(1+0.01) + 4/(9+0.01)) / 2.
        assert!((m.relmse - (1.0 / 1.01 + 4.0 / 9.01) / 2.0).abs() < 1e-12);
        // NRMSE red: sqrt(2.5) / mean(1, 3).
        assert!((m.nrmse - 2.5f64.sqrt() / 2.0).abs() < 1e-12);
        assert!(metrics(&img, &Image::new(1, 1)).is_err());
    }

    #[test]
    fn merge_weights_by_sample_count() {
        let a = Image { width: 1, height: 1, pixels: vec![rgb(1.0, 2.0, 3.0)] };
        let b = Image { width: 1, height: 1, pixels: vec![rgb(4.0, 5.0, 6.0)] };
        let m = merge_weighted(&[(a.clone(), 1.0), (b, 2.0)]).unwrap();
        assert_eq!(m.pixels[0], rgb(3.0, 4.0, 5.0));
        assert!(merge_weighted(&[(a.clone(), 1.0), (Image::new(2, 1), 1.0)]).is_err());
        assert!(merge_weighted(&[(a, 0.0)]).is_err());
        assert!(merge_weighted(&[]).is_err());
    }

    #[test]
    fn t_statistic_detects_bias() {
        let mut rng = crate::sampling::Rng::new(1, 2, 3);
        let reference = Image { width: 32, height: 32, pixels: vec![Rgb::splat(1.0); 1024] };
        let noisy = |rng: &mut crate::sampling::Rng, bias: f32| Image {
            width: 32,
            height: 32,
            pixels: (0..1024).map(|_| Rgb::splat(1.0 + bias + (rng.next_f32() - 0.5))).collect(),
        };
        let (a, b) = (noisy(&mut rng, 0.0), noisy(&mut rng, 0.0));
        let t = block_t_statistic(&a, &b, &reference, 8);
        assert!(t < 3.0, "{t}");
        let tw = relative_block_t_statistic(&a, &b, &reference, None, 8);
        assert!(tw < 3.0, "{tw}");
        let (a, b) = (noisy(&mut rng, 0.2), noisy(&mut rng, 0.2));
        assert!(block_t_statistic(&a, &b, &reference, 8) > 20.0);
        assert!(relative_block_t_statistic(&a, &b, &reference, None, 8) > 20.0);
    }

    #[test]
    fn t_statistic_allows_for_a_noisy_reference() {
        // A reference 10× noisier (per pixel) than two nearly exact renders of the truth.
        let mut rng = crate::sampling::Rng::new(4, 5, 6);
        let mut image = |sigma: f32| Image {
            width: 32,
            height: 32,
            pixels: (0..1024).map(|_| Rgb::splat(1.0 + sigma * (rng.next_f32() - 0.5) * 12f32.sqrt())).collect(),
        };
        let (a, b, reference) = (image(0.01), image(0.01), image(0.1));
        assert!(relative_block_t_statistic(&a, &b, &reference, None, 8) > 20.0);
        let variance = Image { width: 32, height: 32, pixels: vec![Rgb::splat(0.01); 1024] };
        let t = relative_block_t_statistic(&a, &b, &reference, Some(&variance), 8);
        assert!(t < 3.0 && t > 0.3, "{t}");
        // It does not hide a bias larger than the reference's noise.
        let biased = |img: &Image| Image { pixels: img.pixels.iter().map(|p| *p * 1.1).collect(), ..img.clone() };
        assert!(relative_block_t_statistic(&biased(&a), &biased(&b), &reference, Some(&variance), 8) > 20.0);
    }
}
