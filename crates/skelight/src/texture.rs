//! Spatially varying parameters: constants, bitmaps, checkerboards and scaled textures,
//! looked up by surface texture coordinates with Mitsuba's conventions.

use std::sync::Arc;

use crate::color::{srgb_to_linear, Rgb};
use crate::imageio::Image;
use crate::math::{vec2, Vec2};

/// 2D affine map applied to texture coordinates (`to_uv`, `uvscale`, `uoffset`…).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UvTransform {
    /// Row-major 2×3: u' = a·u + b·v + c, v' = d·u + e·v + f.
    pub m: [f32; 6],
}

impl Default for UvTransform {
    fn default() -> Self {
        UvTransform::IDENTITY
    }
}

impl UvTransform {
    pub const IDENTITY: UvTransform = UvTransform { m: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0] };
    pub fn scale_offset(su: f32, sv: f32, ou: f32, ov: f32) -> UvTransform {
        UvTransform { m: [su, 0.0, ou, 0.0, sv, ov] }
    }
    #[inline]
    pub fn apply(&self, uv: Vec2) -> Vec2 {
        let m = &self.m;
        vec2(m[0] * uv.x + m[1] * uv.y + m[2], m[3] * uv.x + m[4] * uv.y + m[5])
    }
    /// `self` after `first`.
    pub fn compose(&self, first: &UvTransform) -> UvTransform {
        let a = &self.m;
        let b = &first.m;
        UvTransform {
            m: [
                a[0] * b[0] + a[1] * b[3],
                a[0] * b[1] + a[1] * b[4],
                a[0] * b[2] + a[1] * b[5] + a[2],
                a[3] * b[0] + a[4] * b[3],
                a[3] * b[1] + a[4] * b[4],
                a[3] * b[2] + a[4] * b[5] + a[5],
            ],
        }
    }
}

/// How bitmap texels are interpolated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TexFilter {
    Nearest,
    Bilinear,
}

/// A decoded bitmap in linear values (sRGB decoded unless the scene asked for raw values).
#[derive(Debug)]
pub struct Bitmap {
    pub image: Image,
    pub filter: TexFilter,
    /// Mean value, for sampling weights and for the scalar interpretation.
    pub mean: Rgb,
}

impl Bitmap {
    /// `srgb`: whether stored values are sRGB-encoded and must be linearised.
    pub fn new(mut image: Image, srgb: bool, filter: TexFilter) -> Bitmap {
        if srgb {
            image.pixels.iter_mut().for_each(|p| *p = p.map(srgb_to_linear));
        }
        let n = image.pixels.len().max(1) as f64;
        let sum =
            image.pixels.iter().fold([0.0f64; 3], |a, p| [a[0] + p.r as f64, a[1] + p.g as f64, a[2] + p.b as f64]);
        let mean = Rgb::from_array(sum.map(|s| (s / n) as f32));
        Bitmap { image, filter, mean }
    }

    /// Value at `uv` with repeat wrapping; uv (0,0) is the top-left texel, as in Mitsuba.
    pub fn eval(&self, uv: Vec2) -> Rgb {
        let (w, h) = (self.image.width as i64, self.image.height as i64);
        let fetch = |x: i64, y: i64| self.image.pixels[(y.rem_euclid(h) * w + x.rem_euclid(w)) as usize];
        let x = uv.x * w as f32 - 0.5;
        let y = uv.y * h as f32 - 0.5;
        if !x.is_finite() || !y.is_finite() {
            return Rgb::BLACK;
        }
        match self.filter {
            TexFilter::Nearest => fetch((x + 0.5).floor() as i64, (y + 0.5).floor() as i64),
            TexFilter::Bilinear => {
                let (x0, y0) = (x.floor(), y.floor());
                let (fx, fy) = (x - x0, y - y0);
                let (x0, y0) = (x0 as i64, y0 as i64);
                fetch(x0, y0) * ((1.0 - fx) * (1.0 - fy))
                    + fetch(x0 + 1, y0) * (fx * (1.0 - fy))
                    + fetch(x0, y0 + 1) * ((1.0 - fx) * fy)
                    + fetch(x0 + 1, y0 + 1) * (fx * fy)
            }
        }
    }
}

/// A texture: anything a material parameter can be bound to.
#[derive(Clone, Debug)]
pub enum Texture {
    Constant(Rgb),
    Bitmap { bitmap: Arc<Bitmap>, to_uv: UvTransform },
    Checkerboard { color0: Rgb, color1: Rgb, to_uv: UvTransform },
    Scale { scale: f32, inner: Box<Texture> },
}

impl Texture {
    pub fn constant(v: f32) -> Texture {
        Texture::Constant(Rgb::splat(v))
    }

    pub fn eval(&self, uv: Vec2) -> Rgb {
        match self {
            Texture::Constant(c) => *c,
            Texture::Bitmap { bitmap, to_uv } => bitmap.eval(to_uv.apply(uv)),
            Texture::Checkerboard { color0, color1, to_uv } => {
                let p = to_uv.apply(uv);
                let (fu, fv) = (p.x - p.x.floor(), p.y - p.y.floor());
                if (fu > 0.5) == (fv > 0.5) {
                    *color0
                } else {
                    *color1
                }
            }
            Texture::Scale { scale, inner } => inner.eval(uv) * *scale,
        }
    }

    /// Scalar reading (roughness, opacity, bump height): the channel mean.
    pub fn eval_scalar(&self, uv: Vec2) -> f32 {
        self.eval(uv).mean()
    }

    /// Largest value per channel over the texture's domain, for bounds on reflectance.
    pub fn max(&self) -> Rgb {
        let per_channel = |a: Rgb, b: Rgb| Rgb::from_array([a.r.max(b.r), a.g.max(b.g), a.b.max(b.b)]);
        match self {
            Texture::Constant(c) => *c,
            Texture::Bitmap { bitmap, .. } => bitmap.image.pixels.iter().fold(Rgb::BLACK, |m, p| per_channel(m, *p)),
            Texture::Checkerboard { color0, color1, .. } => per_channel(*color0, *color1),
            Texture::Scale { scale, inner } => inner.max() * *scale,
        }
    }

    /// Average over the texture's domain, for sampling weights.
    pub fn mean(&self) -> Rgb {
        match self {
            Texture::Constant(c) => *c,
            Texture::Bitmap { bitmap, .. } => bitmap.mean,
            Texture::Checkerboard { color0, color1, .. } => (*color0 + *color1) * 0.5,
            Texture::Scale { scale, inner } => inner.mean() * *scale,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::color::rgb;

    fn two_by_one() -> Bitmap {
        Bitmap::new(
            Image { width: 2, height: 1, pixels: vec![rgb(0.0, 0.0, 0.0), rgb(1.0, 1.0, 1.0)] },
            false,
            TexFilter::Bilinear,
        )
    }

    #[test]
    fn bilinear_hits_texel_centres_and_wraps() {
        let b = two_by_one();
        assert!((b.eval(vec2(0.25, 0.5)).r - 0.0).abs() < 1e-6);
        assert!((b.eval(vec2(0.75, 0.5)).r - 1.0).abs() < 1e-6);
        assert!((b.eval(vec2(0.5, 0.5)).r - 0.5).abs() < 1e-6);
        // Left edge blends with the wrapped right texel.
        assert!((b.eval(vec2(0.0, 0.5)).r - 0.5).abs() < 1e-6);
        assert!((b.eval(vec2(1.25, 0.5)).r - 0.0).abs() < 1e-6);
    }

    #[test]
    fn checkerboard_and_uv_transform() {
        let t = Texture::Checkerboard {
            color0: Rgb::splat(1.0),
            color1: Rgb::splat(0.0),
            to_uv: UvTransform::scale_offset(2.0, 2.0, 0.0, 0.0),
        };
        assert_eq!(t.eval(vec2(0.1, 0.1)).r, 1.0);
        assert_eq!(t.eval(vec2(0.3, 0.1)).r, 0.0);
        let a = UvTransform::scale_offset(2.0, 3.0, 0.5, 0.0);
        let b = UvTransform::scale_offset(1.0, 1.0, 0.0, 1.0);
        let c = a.compose(&b);
        let p = c.apply(vec2(1.0, 1.0));
        assert_eq!((p.x, p.y), (2.5, 6.0));
    }
}
