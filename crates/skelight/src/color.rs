//! Linear RGB radiance values and the sRGB transfer curve.

use std::ops::{Add, AddAssign, Div, Mul, MulAssign, Sub};

/// Linear-RGB quantity (radiance, reflectance, throughput).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Rgb {
    pub r: f32,
    pub g: f32,
    pub b: f32,
}

#[inline]
pub const fn rgb(r: f32, g: f32, b: f32) -> Rgb {
    Rgb { r, g, b }
}

impl Rgb {
    pub const BLACK: Rgb = rgb(0.0, 0.0, 0.0);
    pub const WHITE: Rgb = rgb(1.0, 1.0, 1.0);
    pub const fn splat(v: f32) -> Rgb {
        rgb(v, v, v)
    }
    #[inline]
    pub fn is_black(self) -> bool {
        self.r == 0.0 && self.g == 0.0 && self.b == 0.0
    }
    #[inline]
    pub fn max_component(self) -> f32 {
        self.r.max(self.g).max(self.b)
    }
    #[inline]
    pub fn mean(self) -> f32 {
        (self.r + self.g + self.b) / 3.0
    }
    /// Rec. 709 luminance.
    #[inline]
    pub fn luminance(self) -> f32 {
        0.212671 * self.r + 0.715160 * self.g + 0.072169 * self.b
    }
    #[inline]
    pub fn is_finite(self) -> bool {
        self.r.is_finite() && self.g.is_finite() && self.b.is_finite()
    }
    #[inline]
    pub fn map(self, f: impl Fn(f32) -> f32) -> Rgb {
        rgb(f(self.r), f(self.g), f(self.b))
    }
    pub fn to_array(self) -> [f32; 3] {
        [self.r, self.g, self.b]
    }
    pub fn from_array(a: [f32; 3]) -> Rgb {
        rgb(a[0], a[1], a[2])
    }
}

impl Add for Rgb {
    type Output = Rgb;
    #[inline]
    fn add(self, o: Rgb) -> Rgb {
        rgb(self.r + o.r, self.g + o.g, self.b + o.b)
    }
}
impl AddAssign for Rgb {
    #[inline]
    fn add_assign(&mut self, o: Rgb) {
        *self = *self + o;
    }
}
impl Sub for Rgb {
    type Output = Rgb;
    #[inline]
    fn sub(self, o: Rgb) -> Rgb {
        rgb(self.r - o.r, self.g - o.g, self.b - o.b)
    }
}
impl Mul for Rgb {
    type Output = Rgb;
    #[inline]
    fn mul(self, o: Rgb) -> Rgb {
        rgb(self.r * o.r, self.g * o.g, self.b * o.b)
    }
}
impl MulAssign for Rgb {
    #[inline]
    fn mul_assign(&mut self, o: Rgb) {
        *self = *self * o;
    }
}
impl Mul<f32> for Rgb {
    type Output = Rgb;
    #[inline]
    fn mul(self, s: f32) -> Rgb {
        rgb(self.r * s, self.g * s, self.b * s)
    }
}
impl MulAssign<f32> for Rgb {
    #[inline]
    fn mul_assign(&mut self, s: f32) {
        *self = *self * s;
    }
}
impl Div<f32> for Rgb {
    type Output = Rgb;
    #[inline]
    fn div(self, s: f32) -> Rgb {
        self * (1.0 / s)
    }
}
impl Div for Rgb {
    type Output = Rgb;
    #[inline]
    fn div(self, o: Rgb) -> Rgb {
        rgb(self.r / o.r, self.g / o.g, self.b / o.b)
    }
}

/// sRGB-encoded value (0..1) to linear.
pub fn srgb_to_linear(v: f32) -> f32 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// Linear value to sRGB encoding (0..1, clamped).
pub fn linear_to_srgb(v: f32) -> f32 {
    let v = v.clamp(0.0, 1.0);
    if v <= 0.0031308 {
        v * 12.92
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn srgb_round_trip() {
        for i in 0..=20 {
            let v = i as f32 / 20.0;
            assert!((srgb_to_linear(linear_to_srgb(v)) - v).abs() < 1e-5);
        }
        assert!((srgb_to_linear(0.5) - 0.21404).abs() < 1e-4);
    }
}
