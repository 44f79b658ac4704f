//! Mitsuba 3's `sunsky` emitter in RGB: the Hosek–Wilkie sky (2012) and solar disk (2013).
//!
//! The sky's nine parameters and mean radiance per channel are interpolated linearly in
//! turbidity and ground albedo and along a quintic Bézier curve in the cube root of the sun's
//! elevation; the sun is a uniform disk whose irradiance comes from the model's table (Mitsuba
//! 3's default), or with `complex_sun` a disk darkening towards its limb, of the same power.
//! The tables (`data/sunsky.bin`, 148 KB) are derived from the datasets Mitsuba ships by
//! `scripts/sunsky_data.py`; values agree with Mitsuba 3.9.1's `scalar_rgb` evaluation
//! (tests below). The emitter's local frame is Z-up with X north.
//!
//! Sampling is ours, not Mitsuba's Gaussian mixture: the sky from a piecewise-constant table
//! over the upper hemisphere, the sun uniformly in its cone, chosen by their powers.

use crate::color::{rgb, Rgb};
use crate::light::Environment;
use crate::math::{vec2, vec3, Frame, Transform, Vec2, Vec3, PI};
use crate::sampling::Distribution2D;

/// Tables of the Hosek–Wilkie model, see `scripts/sunsky_data.py` for the layout.
const DATA: &[u8] = include_bytes!("../../data/sunsky.bin");
const MAGIC: &[u8; 8] = b"SKYRGB02";
const TURBIDITY_LEVELS: usize = 10;
const ALBEDO_LEVELS: usize = 2;
const BEZIER_POINTS: usize = 6;
const SKY_PARAMS: usize = 9;
/// The sun's irradiance is tabulated at elevations 2°, 5°, …, 89°.
const SUN_ELEVATIONS: usize = 30;
const SKY_PARAMS_LEN: usize = TURBIDITY_LEVELS * ALBEDO_LEVELS * BEZIER_POINTS * 3 * SKY_PARAMS;
const SKY_RADIANCE_LEN: usize = TURBIDITY_LEVELS * ALBEDO_LEVELS * BEZIER_POINTS * 3;
const SUN_IRRADIANCE_LEN: usize = TURBIDITY_LEVELS * SUN_ELEVATIONS * 3;
/// The limb-darkened disk: a polynomial per segment of elevation (cube-root spaced), of
/// degree 3 in the elevation and 5 in cos ψ.
const LIMB_SEGMENTS: usize = 45;
const LIMB_X_TERMS: usize = 4;
const LIMB_PSI_TERMS: usize = 6;
const LIMB_SEGMENT_LEN: usize = 3 * LIMB_X_TERMS * LIMB_PSI_TERMS;
const SUN_LIMB_LEN: usize = TURBIDITY_LEVELS * LIMB_SEGMENTS * LIMB_SEGMENT_LEN;
/// Full angle subtended by the sun seen from the earth, in degrees (Mitsuba's default).
pub const SUN_APERTURE_DEG: f32 = 0.5358;
/// Resolution of the sky's sampling table over the upper hemisphere (azimuth × polar angle).
const TABLE_PHI: usize = 128;
const TABLE_THETA: usize = 64;

/// Where the sun is: a direction in world space, or a place and a local time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SunPosition {
    Direction(Vec3),
    DateTime(DateTime),
}

/// Place and local time for the solar position (Mitsuba 3's defaults: Tokyo, 10 July 2010, 15:00).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DateTime {
    pub latitude: f64,
    pub longitude: f64,
    /// Hours ahead of UTC.
    pub timezone: f64,
    pub year: i32,
    pub month: i32,
    pub day: i32,
    pub hour: f64,
    pub minute: f64,
    pub second: f64,
}

impl Default for DateTime {
    fn default() -> DateTime {
        DateTime {
            latitude: 35.6894,
            longitude: 139.6917,
            timezone: 9.0,
            year: 2010,
            month: 7,
            day: 10,
            hour: 15.0,
            minute: 0.0,
            second: 0.0,
        }
    }
}

/// Parameters of a `sunsky` emitter, with Mitsuba 3's names and defaults.
#[derive(Clone, Copy, Debug)]
pub struct SunSkyParams {
    /// Atmospheric turbidity in [1, 10].
    pub turbidity: f32,
    /// Ground albedo per channel, in [0, 1].
    pub albedo: Rgb,
    pub sun: SunPosition,
    pub sun_scale: f32,
    pub sky_scale: f32,
    /// Full angle of the sun's disk in degrees; the sun's irradiance stays the same.
    pub sun_aperture_deg: f32,
    /// Darken the disk towards its limb (Mitsuba's `complex_sun`); same power.
    pub complex_sun: bool,
    /// Emitter to world (the emitter's frame is Z-up).
    pub to_world: Transform,
}

impl Default for SunSkyParams {
    fn default() -> SunSkyParams {
        SunSkyParams {
            turbidity: 3.0,
            albedo: Rgb::splat(0.3),
            sun: SunPosition::DateTime(DateTime::default()),
            sun_scale: 1.0,
            sky_scale: 1.0,
            sun_aperture_deg: SUN_APERTURE_DEG,
            complex_sun: false,
            to_world: Transform::IDENTITY,
        }
    }
}

/// The sky and sun, ready to evaluate and sample.
#[derive(Debug)]
pub struct SunSky {
    to_world: Transform,
    to_local: Transform,
    /// Unit direction towards the sun's centre, local frame.
    sun: Vec3,
    /// Hosek–Wilkie parameters A…I per channel for this sun elevation, turbidity and albedo.
    sky_params: [[f32; SKY_PARAMS]; 3],
    /// Mean radiance per channel (includes `sky_scale`).
    sky_radiance: Rgb,
    /// Radiance of the sun's disk (includes `sun_scale`).
    sun_radiance: Rgb,
    /// With `complex_sun`: the limb-darkening polynomials for this turbidity, by segment,
    /// scaled like `sun_radiance`.
    limb: Option<Vec<[f32; LIMB_SEGMENT_LEN]>>,
    /// sin² and 1 − cos of the sun's half aperture: disk membership and cone sampling stay
    /// exact for a half-degree disk, where 1 − cos in f32 would lose most of its digits.
    sun_sin2: f32,
    sun_one_minus_cos: f32,
    sun_frame: Frame,
    /// Sky table over (azimuth, polar angle) of the upper hemisphere.
    sky_table: Distribution2D,
    /// Probability of sampling the sky rather than the sun.
    sky_weight: f32,
    /// ∫ L dω over all directions (channel mean), for choosing lights by power.
    radiance_integral: f32,
}

/// A direction's angle γ from the sun's centre: cos γ, and sin²γ (exact next to the centre,
/// where 1 − cos γ in f32 loses its digits).
struct ToSun {
    cos: f32,
    sin2: f32,
}

/// The tables as floats, checked once.
struct Tables {
    sky_params: &'static [u8],
    sky_radiance: &'static [u8],
    sun_irradiance: &'static [u8],
    sun_limb: &'static [u8],
}

impl Tables {
    fn get() -> Tables {
        let body = &DATA[MAGIC.len()..];
        assert!(
            DATA.starts_with(MAGIC)
                && body.len() == 4 * (SKY_PARAMS_LEN + SKY_RADIANCE_LEN + SUN_IRRADIANCE_LEN + SUN_LIMB_LEN),
            "data/sunsky.bin is not the table file this build expects (regenerate with scripts/sunsky_data.py)"
        );
        let (sky_params, rest) = body.split_at(4 * SKY_PARAMS_LEN);
        let (sky_radiance, rest) = rest.split_at(4 * SKY_RADIANCE_LEN);
        let (sun_irradiance, sun_limb) = rest.split_at(4 * SUN_IRRADIANCE_LEN);
        Tables { sky_params, sky_radiance, sun_irradiance, sun_limb }
    }
}

fn value(bytes: &[u8], i: usize) -> f32 {
    f32::from_le_bytes(bytes[4 * i..4 * i + 4].try_into().unwrap())
}

/// Two table indices and the weight of the upper one for a position `x` in [0, n − 1].
fn lerp_indices(x: f32, n: usize) -> (usize, usize, f32) {
    let x = x.clamp(0.0, (n - 1) as f32);
    let i = (x as usize).min(n - 2);
    (i, i + 1, x - i as f32)
}

impl SunSky {
    pub fn new(p: &SunSkyParams) -> Result<SunSky, String> {
        if !(1.0..=10.0).contains(&p.turbidity) {
            return Err(format!("turbidity {} is outside [1, 10]", p.turbidity));
        }
        if !(p.albedo.to_array().iter().all(|a| (0.0..=1.0).contains(a))) {
            return Err(format!("albedo {:?} is outside [0, 1]", p.albedo.to_array()));
        }
        if !(p.sun_scale >= 0.0 && p.sky_scale >= 0.0 && p.sun_scale.is_finite() && p.sky_scale.is_finite()) {
            return Err(format!("sun_scale {} and sky_scale {} must be finite and ≥ 0", p.sun_scale, p.sky_scale));
        }
        if !(p.sun_aperture_deg > 0.0 && p.sun_aperture_deg < 180.0) {
            return Err(format!("sun_aperture {}° is outside ]0, 180[", p.sun_aperture_deg));
        }
        let to_local = p.to_world.inverse();
        let sun = match p.sun {
            SunPosition::Direction(d) => to_local.vector(d),
            SunPosition::DateTime(t) => solar_direction(&t),
        };
        if !(sun.length() > 0.0) || !sun.is_finite() {
            return Err("the sun direction must be a non-zero vector".into());
        }
        let sun = sun.normalize();
        let t = Tables::get();

        // Mitsuba darkens sky and sun alike once the sun is below the horizon.
        let daylight = if sun.z >= 0.0 { 1.0 } else { 0.0 };
        let elevation = sun.z.clamp(0.0, 1.0).asin();
        let (sky_params, sky_mean) = sky_coefficients(&t, p.turbidity, p.albedo, elevation);
        let sky_radiance = Rgb::from_array(sky_mean) * (p.sky_scale * daylight);

        let half = 0.5 * (p.sun_aperture_deg as f64).to_radians();
        let one_minus_cos = 2.0 * (0.5 * half).sin().powi(2);
        let solid_angle = 2.0 * std::f64::consts::PI * one_minus_cos;
        let irradiance = sun_irradiance(&t, p.turbidity, elevation);
        let sun_radiance = irradiance * ((p.sun_scale * daylight) as f64 / solid_angle) as f32;
        // The limb polynomials give the radiance of the standard half-degree disk; a wider
        // one is dimmer by the ratio of solid angles, as the uniform disk is.
        let standard = 2.0 * (0.25 * (SUN_APERTURE_DEG as f64).to_radians()).sin().powi(2);
        let limb_scale = (p.sun_scale * daylight) as f64 * standard / one_minus_cos;
        let limb = p.complex_sun.then(|| sun_limb(&t, p.turbidity, limb_scale as f32));

        let mut sky = SunSky {
            to_world: p.to_world,
            to_local,
            sun,
            sky_params,
            sky_radiance,
            sun_radiance,
            limb,
            sun_sin2: half.sin().powi(2) as f32,
            sun_one_minus_cos: one_minus_cos as f32,
            sun_frame: Frame::from_normal(sun),
            sky_table: Distribution2D::new(&[1.0], 1, 1),
            sky_weight: 0.0,
            radiance_integral: 0.0,
        };
        let (weights, sky_power) = sky.tabulate_sky();
        sky.sky_table = Distribution2D::new(&weights, TABLE_PHI, TABLE_THETA);
        let sun_power = sun_radiance.mean() * solid_angle as f32;
        let total = sky_power + sun_power;
        sky.sky_weight = if total > 0.0 { sky_power / total } else { 1.0 };
        sky.radiance_integral = total;
        Ok(sky)
    }

    /// Whether the sun is below the horizon (everything is then dark, as in Mitsuba 3).
    pub fn sun_below_horizon(&self) -> bool {
        self.sun.z < 0.0
    }

    /// Angle between local direction `d` (unit) and the sun's centre, measured once for
    /// the sky, the disk test and the limb.
    fn to_sun(&self, d: Vec3) -> ToSun {
        ToSun { cos: d.dot(self.sun).clamp(-1.0, 1.0), sin2: d.cross(self.sun).length_squared() }
    }

    /// Sky radiance (without the sun) in local direction `d` (unit), at `to_sun` from it.
    fn sky(&self, d: Vec3, to_sun: &ToSun) -> Rgb {
        let cos_theta = d.z;
        if cos_theta < 0.0 || self.sky_radiance.is_black() {
            return Rgb::BLACK;
        }
        let cos_gamma = to_sun.cos;
        let gamma = to_sun.sin2.sqrt().atan2(cos_gamma);
        let channel = |c: usize| {
            let [a, b, cc, dd, e, f, g, h, i] = self.sky_params[c];
            let c1 = 1.0 + a * (b / (cos_theta + 0.01)).exp();
            let chi = (1.0 + cos_gamma * cos_gamma) / (1.0 + i * i - 2.0 * i * cos_gamma).powf(1.5);
            let c2 = cc + dd * (e * gamma).exp() + f * cos_gamma * cos_gamma + g * chi + h * cos_theta.sqrt();
            c1 * c2
        };
        let s = self.sky_radiance;
        rgb(channel(0) * s.r, channel(1) * s.g, channel(2) * s.b)
    }

    /// Whether a direction at `to_sun` from the sun's centre lies in its disk.
    fn in_sun(&self, to_sun: &ToSun) -> bool {
        to_sun.cos > 0.0 && to_sun.sin2 <= self.sun_sin2
    }

    fn eval_local(&self, d: Vec3) -> Rgb {
        if d.z < 0.0 {
            return Rgb::BLACK;
        }
        let to_sun = self.to_sun(d);
        let sun = match &self.limb {
            _ if !self.in_sun(&to_sun) => Rgb::BLACK,
            None => self.sun_radiance,
            Some(limb) => self.limb_darkened(limb, d, to_sun.sin2),
        };
        self.sky(d, &to_sun) + sun
    }

    /// Radiance of the limb-darkened disk towards local direction `d` (in the disk), whose
    /// angle γ from the disk's centre has sin²γ = `sin2_gamma`.
    fn limb_darkened(&self, limb: &[[f32; LIMB_SEGMENT_LEN]], d: Vec3, sin2_gamma: f32) -> Rgb {
        let elevation = d.z.clamp(0.0, 1.0).asin();
        let segment = (((2.0 * elevation / PI).cbrt() * LIMB_SEGMENTS as f32) as usize).min(LIMB_SEGMENTS - 1);
        let x = elevation - 0.5 * PI * (segment as f32 / LIMB_SEGMENTS as f32).powi(3);
        // cos ψ: ψ the angle between the disk's centre and the seen point, from the sun.
        let cos_psi = (1.0 - sin2_gamma / self.sun_sin2).max(0.0).sqrt();
        let coefficients = &limb[segment];
        let mut out = [0.0f32; 3];
        for (c, value) in out.iter_mut().enumerate() {
            let mut x_power = 1.0;
            for k in 0..LIMB_X_TERMS {
                let row = &coefficients[(c * LIMB_X_TERMS + k) * LIMB_PSI_TERMS..][..LIMB_PSI_TERMS];
                let in_psi = row.iter().rev().fold(0.0, |acc, &a| acc * cos_psi + a);
                *value += x_power * in_psi;
                x_power *= x;
            }
        }
        Rgb::from_array(out)
    }

    /// Direction of a point (u, v) of the sky table: azimuth 2πu, polar angle πv/2; and sinθ.
    fn table_direction(uv: Vec2) -> (Vec3, f32) {
        let (sp, cp) = (2.0 * PI * uv.x).sin_cos();
        let (st, ct) = (0.5 * PI * uv.y).sin_cos();
        (vec3(st * cp, st * sp, ct), st)
    }

    /// Sampling weights of the sky table (the brightest of nine points of each cell times
    /// its sinθ, so the circumsolar peak is not missed) and the sky's radiance integral.
    fn tabulate_sky(&self) -> (Vec<f32>, f32) {
        let mut weights = vec![0.0f32; TABLE_PHI * TABLE_THETA];
        let mut integral = 0.0f64;
        let cell = (2.0 * PI / TABLE_PHI as f32) * (0.5 * PI / TABLE_THETA as f32);
        for j in 0..TABLE_THETA {
            for i in 0..TABLE_PHI {
                let mut brightest = 0.0f32;
                for (a, b) in (0..9).map(|k| ((k % 3) as f32 * 0.5, (k / 3) as f32 * 0.5)) {
                    let uv = vec2((i as f32 + a) / TABLE_PHI as f32, (j as f32 + b) / TABLE_THETA as f32);
                    let d = Self::table_direction(uv).0;
                    brightest = brightest.max(self.sky(d, &self.to_sun(d)).max_component());
                }
                let (d, sin_theta) = Self::table_direction(vec2(
                    (i as f32 + 0.5) / TABLE_PHI as f32,
                    (j as f32 + 0.5) / TABLE_THETA as f32,
                ));
                weights[j * TABLE_PHI + i] = brightest * sin_theta;
                integral += (self.sky(d, &self.to_sun(d)).mean() * sin_theta * cell) as f64;
            }
        }
        (weights, integral as f32)
    }

    /// Solid-angle densities of the sky table and of the sun's cone at local direction `d`.
    fn pdf_local(&self, d: Vec3) -> f32 {
        let mut pdf = 0.0;
        if self.sky_weight > 0.0 && d.z >= 0.0 {
            let sin_theta = (d.x * d.x + d.y * d.y).sqrt();
            if sin_theta > 0.0 {
                let mut phi = d.y.atan2(d.x) / (2.0 * PI);
                phi -= phi.floor();
                let theta = sin_theta.atan2(d.z) / (0.5 * PI);
                pdf += self.sky_weight * self.sky_table.pdf(vec2(phi, theta)) / (PI * PI * sin_theta);
            }
        }
        if self.sky_weight < 1.0 && self.in_sun(&self.to_sun(d)) {
            pdf += (1.0 - self.sky_weight) / (2.0 * PI * self.sun_one_minus_cos);
        }
        pdf
    }

    /// A direction in the sun's cone, uniformly.
    fn sample_sun(&self, u: Vec2) -> Vec3 {
        let one_minus_cos = u.x * self.sun_one_minus_cos;
        let cos_t = 1.0 - one_minus_cos;
        let sin_t = (one_minus_cos * (2.0 - one_minus_cos)).max(0.0).sqrt();
        let (sp, cp) = (2.0 * PI * u.y).sin_cos();
        self.sun_frame.to_world(vec3(sin_t * cp, sin_t * sp, cos_t))
    }
}

impl Environment for SunSky {
    fn eval(&self, d: Vec3) -> Rgb {
        self.eval_local(self.to_local.vector(d).normalize())
    }

    fn sample(&self, u: Vec2) -> Option<(Vec3, Rgb, f32)> {
        if self.radiance_integral <= 0.0 {
            return None;
        }
        let local = if u.x < self.sky_weight {
            let (uv, _) = self.sky_table.sample(vec2(u.x / self.sky_weight, u.y));
            Self::table_direction(uv).0
        } else {
            self.sample_sun(vec2((u.x - self.sky_weight) / (1.0 - self.sky_weight), u.y))
        };
        let pdf = self.pdf_local(local);
        if !(pdf > 0.0) {
            return None;
        }
        // Radiance of the world direction as returned, so that it equals eval() exactly: at
        // the limb of a darkened sun a rounding of the direction moves cos ψ visibly.
        let d = self.to_world.vector(local).normalize();
        Some((d, self.eval(d), pdf))
    }

    fn pdf(&self, d: Vec3) -> f32 {
        self.pdf_local(self.to_local.vector(d).normalize())
    }

    fn radiance_integral(&self) -> f32 {
        self.radiance_integral
    }
}

/// Sky parameters and mean radiance per channel for a sun `elevation` (radians).
fn sky_coefficients(t: &Tables, turbidity: f32, albedo: Rgb, elevation: f32) -> ([[f32; SKY_PARAMS]; 3], [f32; 3]) {
    let (t0, t1, wt) = lerp_indices(turbidity - 1.0, TURBIDITY_LEVELS);
    // Quintic Bézier in the cube root of the elevation, as the model was fitted.
    let x = (2.0 * elevation / PI).cbrt().min(1.0 - f32::EPSILON);
    const BINOMIAL: [f32; BEZIER_POINTS] = [1.0, 5.0, 10.0, 10.0, 5.0, 1.0];
    let bezier: [f32; BEZIER_POINTS] =
        std::array::from_fn(|k| BINOMIAL[k] * x.powi(k as i32) * (1.0 - x).powi((BEZIER_POINTS - 1 - k) as i32));
    let albedo = albedo.to_array();
    let mut params = [[0.0f32; SKY_PARAMS]; 3];
    let mut mean = [0.0f32; 3];
    for c in 0..3 {
        for (turb, w_turb) in [(t0, 1.0 - wt), (t1, wt)] {
            for (alb, w_alb) in [(0, 1.0 - albedo[c]), (1, albedo[c])] {
                for (k, w_k) in bezier.iter().enumerate() {
                    let w = w_turb * w_alb * w_k;
                    let row = ((turb * ALBEDO_LEVELS + alb) * BEZIER_POINTS + k) * 3 + c;
                    mean[c] += w * value(t.sky_radiance, row);
                    for (q, param) in params[c].iter_mut().enumerate() {
                        *param += w * value(t.sky_params, row * SKY_PARAMS + q);
                    }
                }
            }
        }
    }
    (params, mean)
}

/// Irradiance of the whole solar disk (RGB) for a sun `elevation` (radians).
fn sun_irradiance(t: &Tables, turbidity: f32, elevation: f32) -> Rgb {
    let (t0, t1, wt) = lerp_indices(turbidity - 1.0, TURBIDITY_LEVELS);
    let (e0, e1, we) = lerp_indices((elevation.to_degrees() - 2.0) / 3.0, SUN_ELEVATIONS);
    let at = |turb: usize, e: usize| {
        let i = (turb * SUN_ELEVATIONS + e) * 3;
        rgb(value(t.sun_irradiance, i), value(t.sun_irradiance, i + 1), value(t.sun_irradiance, i + 2))
    };
    (at(t0, e0) * (1.0 - we) + at(t0, e1) * we) * (1.0 - wt) + (at(t1, e0) * (1.0 - we) + at(t1, e1) * we) * wt
}

/// The limb-darkening polynomials of every elevation segment for `turbidity`, times `scale`.
fn sun_limb(t: &Tables, turbidity: f32, scale: f32) -> Vec<[f32; LIMB_SEGMENT_LEN]> {
    let (t0, t1, wt) = lerp_indices(turbidity - 1.0, TURBIDITY_LEVELS);
    (0..LIMB_SEGMENTS)
        .map(|segment| {
            std::array::from_fn(|i| {
                let at = |turb: usize| value(t.sun_limb, (turb * LIMB_SEGMENTS + segment) * LIMB_SEGMENT_LEN + i);
                scale * (at(t0) * (1.0 - wt) + at(t1) * wt)
            })
        })
        .collect()
}

/// Unit direction towards the sun in the emitter's frame (Z up, X north, azimuth measured
/// as Mitsuba 3 does), from "Computing the solar vector", Blanco-Muriel et al., Solar
/// Energy 70(5), 2001.
pub fn solar_direction(t: &DateTime) -> Vec3 {
    let hours_utc = t.hour - t.timezone + (t.minute + t.second / 60.0) / 60.0;
    // Julian day number by integer arithmetic (truncating division), then days since J2000.0.
    let a = (t.month - 14) / 12;
    let jdn = (1461 * (t.year + 4800 + a)) / 4 + (367 * (t.month - 2 - 12 * a)) / 12
        - (3 * ((t.year + 4900 + a) / 100)) / 4
        + t.day
        - 32075;
    let days = jdn as f64 - 0.5 + hours_utc / 24.0 - 2451545.0;

    // Ecliptic coordinates.
    let omega = 2.1429 - 0.0010394594 * days;
    let mean_longitude = 4.8950630 + 0.017202791698 * days;
    let anomaly = 6.2400600 + 0.0172019699 * days;
    let ecliptic_longitude = mean_longitude + 0.03341607 * anomaly.sin() + 0.00034894 * (2.0 * anomaly).sin()
        - 0.0001134
        - 0.0000203 * omega.sin();
    let obliquity = 0.4090928 - 6.2140e-9 * days + 0.0000396 * omega.cos();

    // Celestial coordinates.
    let sin_lon = ecliptic_longitude.sin();
    let mut right_ascension = (obliquity.cos() * sin_lon).atan2(ecliptic_longitude.cos());
    if right_ascension < 0.0 {
        right_ascension += 2.0 * std::f64::consts::PI;
    }
    let declination = (obliquity.sin() * sin_lon).asin();

    // Local coordinates.
    let gmst = 6.6974243242 + 0.0657098283 * days + hours_utc;
    let lmst = (gmst * 15.0 + t.longitude).to_radians();
    let latitude = t.latitude.to_radians();
    let hour_angle = lmst - right_ascension;
    let mut zenith = (latitude.cos() * hour_angle.cos() * declination.cos() + declination.sin() * latitude.sin())
        .clamp(-1.0, 1.0)
        .acos();
    let mut azimuth = (-hour_angle.sin()).atan2(declination.tan() * latitude.cos() - latitude.sin() * hour_angle.cos());
    if azimuth < 0.0 {
        azimuth += 2.0 * std::f64::consts::PI;
    }
    // Parallax: the observer stands on the earth's surface, not at its centre.
    const EARTH_RADIUS_KM: f64 = 6371.01;
    const ASTRONOMICAL_UNIT_KM: f64 = 149597890.0;
    zenith += EARTH_RADIUS_KM / ASTRONOMICAL_UNIT_KM * zenith.sin();
    let phi = azimuth - std::f64::consts::PI;
    vec3((zenith.sin() * phi.cos()) as f32, (zenith.sin() * phi.sin()) as f32, zenith.cos() as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    type Vector = ([f32; 3], [f32; 3]);

    /// Radiance of Mitsuba 3.9.1's `sunsky` (scalar_rgb) printed by scripts/sunsky_reference.py:
    /// sky directions (one below the horizon), the sun's centre and, for the limb-darkened
    /// sun, points across its disk, per configuration.
    #[allow(clippy::excessive_precision)] // printed verbatim by the script
    fn mitsuba_reference() -> Vec<(SunSkyParams, Vec<Vector>)> {
        let default_sky = SunSkyParams { sun: SunPosition::Direction(vec3(0.3, 0.2, 0.6)), ..Default::default() };
        let hazy = SunSkyParams {
            sun: SunPosition::Direction(vec3(0.9, -0.3, 0.08)),
            turbidity: 6.5,
            sun_aperture_deg: 5.0,
            albedo: rgb(0.1, 0.5, 0.9),
            sky_scale: 2.0,
            sun_scale: 0.5,
            ..Default::default()
        };
        let paris = SunSkyParams {
            sun: SunPosition::DateTime(DateTime {
                latitude: 48.85,
                longitude: 2.35,
                timezone: 1.0,
                year: 2021,
                month: 3,
                day: 2,
                hour: 9.5,
                ..Default::default()
            }),
            turbidity: 2.2,
            to_world: Transform::rotate([0.98058068, 0.19611614, 0.0], -80.0).unwrap(),
            ..Default::default()
        };
        let limb = SunSkyParams { complex_sun: true, ..default_sky };
        let wide_limb = SunSkyParams {
            sun: SunPosition::Direction(vec3(-0.2, 0.5, 0.3)),
            complex_sun: true,
            turbidity: 7.3,
            sun_aperture_deg: 4.0,
            sun_scale: 2.0,
            ..Default::default()
        };
        vec![
            (
                default_sky,
                vec![
                    ([0.0, 0.0, 1.0], [3.513206e-02, 5.518135e-02, 1.050139e-01]),
                    ([0.995037, 0.0, 0.0995037], [1.440408e-01, 2.079414e-01, 2.945871e-01]),
                    ([-0.650945, 0.650945, 0.390567], [4.998684e-02, 8.967882e-02, 1.640484e-01]),
                    ([0.274075, -0.959264, 0.0685189], [1.309643e-01, 1.866284e-01, 2.546854e-01]),
                    ([0.0, 0.980581, 0.196116], [9.634713e-02, 1.518109e-01, 2.406421e-01]),
                    ([0.196116, 0.588348, -0.784465], [0.0, 0.0, 0.0]),
                    ([0.428571, 0.285714, 0.857143], [2.185104e+04, 1.828185e+04, 1.405245e+04]),
                ],
            ),
            (
                hazy,
                vec![
                    ([0.0, 0.0, 1.0], [1.654347e-02, 2.736075e-02, 3.987540e-02]),
                    ([0.995037, 0.0, 0.0995037], [8.235512e-01, 4.820384e-01, 1.618538e-01]),
                    ([-0.650945, 0.650945, 0.390567], [7.378130e-02, 9.214153e-02, 9.298453e-02]),
                    ([0.274075, -0.959264, 0.0685189], [1.577182e-01, 1.274365e-01, 8.223724e-02]),
                    ([0.0, 0.980581, 0.196116], [8.506252e-02, 1.000568e-01, 8.794397e-02]),
                    ([0.196116, 0.588348, -0.784465], [0.0, 0.0, 0.0]),
                    ([0.945328, -0.315109, 0.0840292], [2.060753e+01, 8.581661e+00, 1.303666e+00]),
                ],
            ),
            (
                SunSkyParams::default(),
                vec![
                    ([0.0, 0.0, 1.0], [2.435108e-02, 4.230875e-02, 8.559477e-02]),
                    ([0.995037, 0.0, 0.0995037], [1.115587e-01, 1.663696e-01, 2.331948e-01]),
                    ([-0.650945, 0.650945, 0.390567], [7.110000e-02, 1.122565e-01, 1.832875e-01]),
                    ([0.274075, -0.959264, 0.0685189], [1.450795e-01, 2.070314e-01, 2.665589e-01]),
                    ([0.0, 0.980581, 0.196116], [1.600482e-01, 2.203168e-01, 2.982674e-01]),
                    ([0.196116, 0.588348, -0.784465], [0.0, 0.0, 0.0]),
                    ([0.0513854, 0.691748, 0.720308], [2.141874e+04, 1.762625e+04, 1.304179e+04]),
                ],
            ),
            (
                paris,
                vec![
                    ([0.0, 0.0, 1.0], [1.682187e-01, 2.020710e-01, 2.052558e-01]),
                    ([0.995037, 0.0, 0.0995037], [0.0, 0.0, 0.0]),
                    ([-0.650945, 0.650945, 0.390567], [1.491075e-02, 2.952151e-02, 5.331147e-02]),
                    ([0.274075, -0.959264, 0.0685189], [0.0, 0.0, 0.0]),
                    ([0.0, 0.980581, 0.196116], [1.103275e-02, 2.326278e-02, 4.433493e-02]),
                    ([0.196116, 0.588348, -0.784465], [3.923830e-02, 6.671590e-02, 1.001308e-01]),
                    ([0.328599, 0.208811, 0.921097], [1.873420e+04, 1.341789e+04, 7.083308e+03]),
                ],
            ),
            (
                limb,
                vec![
                    ([0.0, 0.0, 1.0], [3.513206e-02, 5.518135e-02, 1.050139e-01]),
                    ([0.428571463, 0.285714298, 0.857142925], [2.634045e+04, 2.286790e+04, 1.859560e+04]),
                    ([0.429483265, 0.287070274, 0.856233001], [2.534288e+04, 2.183223e+04, 1.753711e+04]),
                    ([0.430393487, 0.288425237, 0.855319977], [2.121670e+04, 1.758755e+04, 1.329009e+04]),
                    ([0.430734485, 0.288933098, 0.854976952], [1.660227e+04, 1.299392e+04, 8.935052e+03]),
                ],
            ),
            (
                wide_limb,
                vec![
                    ([-0.650944555, 0.650944555, 0.390566733], [4.487512e-01, 4.228699e-01, 3.572188e-01]),
                    ([0.0, 0.980580676, 0.196116135], [5.468972e-01, 5.073165e-01, 4.121923e-01]),
                    ([-0.324442834, 0.811107039, 0.486664265], [6.815899e+02, 5.401633e+02, 3.824895e+02]),
                    ([-0.31464988, 0.818737686, 0.480274945], [6.520392e+02, 5.116767e+02, 3.563537e+02]),
                    ([-0.304795593, 0.826208711, 0.473791987], [5.424033e+02, 4.088640e+02, 2.665351e+02]),
                    ([-0.301084816, 0.828968883, 0.471336991], [4.231702e+02, 3.012265e+02, 1.781887e+02]),
                ],
            ),
        ]
    }

    /// Every reference value within 0.5 % (sky: f32 rounding; sun: Mitsuba computes the
    /// disk's solid angle from an f32 cosine, 0.2 % off; the horizon below is exactly black).
    #[test]
    fn radiance_matches_mitsuba() {
        for (params, vectors) in mitsuba_reference() {
            let sky = SunSky::new(&params).unwrap();
            for (d, expected) in vectors {
                let got = sky.eval(Vec3::from(d)).to_array();
                for c in 0..3 {
                    let tol = 5e-3 * expected[c].abs() + 1e-7;
                    assert!((got[c] - expected[c]).abs() <= tol, "{params:?} {d:?}: {got:?} vs {expected:?}");
                }
            }
        }
    }

    #[test]
    fn solar_position_matches_mitsuba() {
        let tokyo = solar_direction(&DateTime::default());
        assert!((tokyo - vec3(0.051385, 0.691748, 0.720308)).length() < 1e-4, "{tokyo:?}");
    }

    /// Importance-sampled ∫ L dω equals a uniform-sphere estimate of the sky plus the sun's
    /// exact part (uniform directions would find the half-degree sun a few times in 10⁶),
    /// and pdf() agrees with sample().
    #[test]
    fn sampling_is_unbiased_and_consistent() {
        let params = SunSkyParams {
            sun: SunPosition::Direction(vec3(0.4, 0.3, 0.5)),
            turbidity: 4.0,
            to_world: Transform::rotate([1.0, 0.0, 0.0], -90.0).unwrap(),
            ..Default::default()
        };
        let sky = SunSky::new(&params).unwrap();
        let sun_part = (sky.sun_radiance.mean() * 2.0 * PI * sky.sun_one_minus_cos) as f64;
        let sky_alone = SunSky::new(&SunSkyParams { sun_scale: 0.0, ..params }).unwrap();
        crate::light::check_environment_sampling(&sky, &sky_alone, sun_part, 400_000);
        assert!(sky.sky_weight > 0.0 && sky.sky_weight < 1.0);
    }

    /// The limb-darkened disk sends what the uniform one does (midpoint rule over the disk,
    /// in its own frame), and sampling stays unbiased with it.
    #[test]
    fn limb_darkening_keeps_the_suns_power() {
        for aperture in [SUN_APERTURE_DEG, 4.0] {
            let params = SunSkyParams {
                sun: SunPosition::Direction(vec3(0.2, -0.4, 0.6)),
                sun_aperture_deg: aperture,
                complex_sun: true,
                ..Default::default()
            };
            let sky = SunSky::new(&params).unwrap();
            let limb = sky.limb.as_ref().unwrap();
            let half = 0.5 * (aperture as f64).to_radians();
            let (rings, sectors) = (2000, 32);
            let mut integral = 0.0f64;
            for i in 0..rings {
                let a = half * (i as f64 + 0.5) / rings as f64;
                for j in 0..sectors {
                    let phi = 2.0 * std::f64::consts::PI * (j as f64 + 0.5) / sectors as f64;
                    let local = vec3((a.sin() * phi.cos()) as f32, (a.sin() * phi.sin()) as f32, a.cos() as f32);
                    let d = sky.sun_frame.to_world(local).normalize();
                    integral += sky.limb_darkened(limb, d, sky.to_sun(d).sin2).mean() as f64 * a.sin();
                }
            }
            integral *= (half / rings as f64) * (2.0 * std::f64::consts::PI / sectors as f64);
            let uniform = (sky.sun_radiance.mean() * 2.0 * PI * sky.sun_one_minus_cos) as f64;
            assert!((integral / uniform - 1.0).abs() < 0.01, "aperture {aperture}: {integral} vs {uniform}");
            let sky_alone = SunSky::new(&SunSkyParams { sun_scale: 0.0, ..params }).unwrap();
            crate::light::check_environment_sampling(&sky, &sky_alone, integral, 200_000);
        }
    }

    #[test]
    fn rejects_out_of_range_parameters() {
        for bad in [
            SunSkyParams { turbidity: 0.5, ..Default::default() },
            SunSkyParams { albedo: rgb(0.2, 1.5, 0.2), ..Default::default() },
            SunSkyParams { sun_scale: -1.0, ..Default::default() },
            SunSkyParams { sun_aperture_deg: 0.0, ..Default::default() },
            SunSkyParams { sun: SunPosition::Direction(Vec3::ZERO), ..Default::default() },
        ] {
            assert!(SunSky::new(&bad).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn sun_below_the_horizon_darkens_everything() {
        let night =
            SunSky::new(&SunSkyParams { sun: SunPosition::Direction(vec3(0.0, 0.3, -1.0)), ..Default::default() })
                .unwrap();
        assert!(night.eval(vec3(0.0, 0.0, 1.0)).is_black());
        assert!(night.sample(vec2(0.3, 0.6)).is_none());
    }
}
