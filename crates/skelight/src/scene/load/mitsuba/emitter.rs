//! Mitsuba emitters outside shapes: point, spot, directional, constant, envmap, and the
//! sun and sky models of Mitsuba 0.x and 3.

use roxmltree::Node;

use super::{Loader, R};
use crate::color::Rgb;
use crate::imageio::Image;
use crate::light::{DateTime, EnvMap, Light, SunPosition, SunSky, SunSkyParams, SUN_APERTURE_DEG};
use crate::math::{vec3, Frame, Transform, Vec3};

impl Loader {
    pub(super) fn emitter(&mut self, n: Node) -> R<()> {
        let ty = self.attr(n, "type")?.unwrap_or_default();
        let to_world = self.transform(n, "to_world")?;
        let light = match ty.as_str() {
            "point" => {
                let pos = self.point(n, "position", to_world.point(Vec3::ZERO))?;
                Light::Point { position: pos, intensity: self.color(n, "intensity", Rgb::WHITE)? }
            }
            "spot" => {
                let cutoff = self.float(n, "cutoff_angle", 20.0)?.to_radians();
                let beam = self.float(n, "beam_width", cutoff.to_degrees() * 0.75)?.to_radians().min(cutoff);
                let forward = to_world.vector(vec3(0.0, 0.0, 1.0)).normalize();
                Light::Spot {
                    position: to_world.point(Vec3::ZERO),
                    frame: Frame::from_normal(forward),
                    intensity: self.color(n, "intensity", Rgb::WHITE)?,
                    cos_cutoff: cutoff.cos(),
                    cutoff,
                    beam_width: beam,
                }
            }
            "directional" => {
                let d = match self.prop(n, "direction") {
                    Some(p) => self.vector3(p)?,
                    None => to_world.vector(vec3(0.0, 0.0, 1.0)),
                };
                if !(d.length() > 0.0) {
                    return Err(self.err(n, "directional light needs a non-zero direction"));
                }
                Light::Directional { direction: d.normalize(), irradiance: self.color(n, "irradiance", Rgb::WHITE)? }
            }
            "constant" => Light::Constant { radiance: self.color(n, "radiance", Rgb::WHITE)? },
            "envmap" => {
                let f = self.string(n, "filename")?.ok_or_else(|| self.err(n, "envmap needs a filename"))?;
                let path = self.resolve(n, &f)?;
                let img = Image::load(&path).map_err(|e| self.err(n, e.to_string()))?;
                let scale = self.float(n, "scale", 1.0)?;
                Light::Env(Box::new(EnvMap::new(img, scale, to_world)))
            }
            "sunsky" | "sun" | "sky" => Light::Env(Box::new(self.sunsky(n, &ty, to_world)?)),
            "area" => return Err(self.err(n, "an area emitter must be inside a <shape>")),
            other => {
                self.warn_at(n, format!("emitter type '{other}' is not supported; ignored"));
                return Ok(());
            }
        };
        self.desc.lights.push(light);
        Ok(())
    }

    /// Mitsuba 3's `sunsky`, and Mitsuba 0.x's `sunsky`, `sun` and `sky` read with their 0.x
    /// names (`sunRadiusScale`, `scale`) and defaults (albedo 0.15) in a Y-up frame, all
    /// rendered with Mitsuba 3's model.
    fn sunsky(&mut self, n: Node, ty: &str, to_world: Transform) -> R<SunSky> {
        let legacy = self.version_major == 0;
        let time_names = ["latitude", "longitude", "timezone", "year", "month", "day", "hour", "minute", "second"];
        let sun = match self.prop(n, "sun_direction") {
            Some(p) => {
                if let Some(t) = time_names.iter().find(|t| self.prop(n, t).is_some()) {
                    return Err(
                        self.err(n, format!("'{ty}' takes either sun_direction or a place and time ('{t}'), not both"))
                    );
                }
                SunPosition::Direction(self.vector3(p)?)
            }
            None => {
                let d = DateTime::default();
                let whole = |s: &Self, name: &str, default: i32| -> R<i32> {
                    let v = s.int(n, name, default as i64)?;
                    i32::try_from(v).map_err(|_| s.err(n, format!("'{name}' = {v} is out of range")))
                };
                SunPosition::DateTime(DateTime {
                    latitude: self.float(n, "latitude", d.latitude as f32)? as f64,
                    longitude: self.float(n, "longitude", d.longitude as f32)? as f64,
                    timezone: self.float(n, "timezone", d.timezone as f32)? as f64,
                    year: whole(self, "year", d.year)?,
                    month: whole(self, "month", d.month)?,
                    day: whole(self, "day", d.day)?,
                    hour: self.float(n, "hour", d.hour as f32)? as f64,
                    minute: self.float(n, "minute", d.minute as f32)? as f64,
                    second: self.float(n, "second", d.second as f32)? as f64,
                })
            }
        };
        // 0.x's `sun` and `sky` are the two halves, each with its own `scale`.
        let scale = self.float(n, "scale", 1.0)?;
        let sun_scale =
            if ty == "sky" { 0.0 } else { self.float(n, "sun_scale", if ty == "sun" { scale } else { 1.0 })? };
        let sky_scale =
            if ty == "sun" { 0.0 } else { self.float(n, "sky_scale", if ty == "sky" { scale } else { 1.0 })? };
        let sun_aperture_deg = match self.prop(n, "sun_radius_scale") {
            Some(_) => SUN_APERTURE_DEG * self.float(n, "sun_radius_scale", 1.0)?,
            None => self.float(n, "sun_aperture", SUN_APERTURE_DEG)?,
        };
        let to_world = if legacy {
            // 0.x skies are Y-up: turn the emitter's Z-up frame onto +Y.
            to_world.compose(&Transform::rotate([1.0, 0.0, 0.0], -90.0).expect("a rotation about x"))
        } else {
            to_world
        };
        let params = SunSkyParams {
            turbidity: self.float(n, "turbidity", 3.0)?,
            albedo: self.color(n, "albedo", Rgb::splat(if legacy { 0.15 } else { 0.3 }))?,
            sun,
            sun_scale,
            sky_scale,
            sun_aperture_deg,
            complex_sun: self.boolean(n, "complex_sun", false)?,
            to_world,
        };
        let sky = SunSky::new(&params).map_err(|e| self.err(n, format!("{ty}: {e}")))?;
        if sky.sun_below_horizon() {
            self.warn_at(n, format!("{ty}: the sun is below the horizon, so sun and sky are dark (as in Mitsuba 3)"));
        }
        Ok(sky)
    }
}

#[cfg(test)]
mod tests {
    use crate::light::Light;
    use crate::math::{vec3, Vec3};

    fn environment_of(name: &str, xml: &str) -> (Box<dyn Fn(Vec3) -> f32>, Vec<String>) {
        let dir = std::env::temp_dir().join(format!("skelight-mitsuba-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("s.xml");
        std::fs::write(&path, xml).unwrap();
        let mut scene = crate::scene::load::load(&path, &[]).unwrap();
        let _ = std::fs::remove_dir_all(&dir);
        let Light::Env(env) = scene.lights.remove(0) else { panic!("not an environment") };
        (Box::new(move |d: Vec3| env.eval(d.normalize()).g), scene.warnings)
    }

    /// Mitsuba 0.x skies are Y-up and take `sunDirection`, `sunRadiusScale` and, for the
    /// separate `sun` and `sky`, a `scale`; Mitsuba 3's is Z-up.
    #[test]
    fn legacy_sun_and_sky_are_read_in_a_y_up_frame() {
        let legacy = |body: &str| format!(r#"<scene version="0.5.0">{body}</scene>"#);
        let (sunsky, _) = environment_of(
            "legacy",
            &legacy(
                r#"<emitter type="sunsky"><vector name="sunDirection" x="0" y="1" z="1"/><float name="sunRadiusScale" value="10"/></emitter>"#,
            ),
        );
        assert!(sunsky(vec3(0.0, 1.0, 0.0)) > 0.0 && sunsky(vec3(0.0, 0.0, 1.0)) > 0.0);
        assert_eq!(sunsky(vec3(0.3, -1.0, 0.0)), 0.0, "below the horizon (−y) is dark");
        // Half aperture 10 × 0.5358° / 2 = 2.68°: 2° off the centre is sun, 3° is sky.
        let off = |deg: f32| {
            let a = 45f32.to_radians() + deg.to_radians();
            vec3(0.0, a.cos(), a.sin())
        };
        assert!(sunsky(off(2.0)) > 100.0 * sunsky(off(3.0)));
        let (sky, _) = environment_of(
            "sky",
            &legacy(
                r#"<emitter type="sky"><vector name="sunDirection" x="0" y="1" z="1"/><float name="scale" value="2"/></emitter>"#,
            ),
        );
        assert!((sky(off(3.0)) - 2.0 * sunsky(off(3.0))).abs() < 1e-4 * sky(off(3.0)), "sky scale and no sun");
        assert!(sky(off(0.0)) < 10.0 * sky(off(3.0)), "no sun in `sky`");
        let (sun, _) = environment_of(
            "sun",
            &legacy(
                r#"<emitter type="sun"><vector name="sunDirection" x="0" y="1" z="1"/><float name="sunRadiusScale" value="10"/></emitter>"#,
            ),
        );
        assert_eq!(sun(off(3.0)), 0.0, "no sky in `sun`");
        assert!(sun(off(0.0)) > 0.0);
        let v3 = |complex: bool| {
            environment_of(
                "v3",
                &format!(
                    r#"<scene version="3.0.0"><emitter type="sunsky"><vector name="sun_direction" value="0, 1, 1"/><boolean name="complex_sun" value="{complex}"/></emitter></scene>"#
                ),
            )
        };
        let (modern, warnings) = v3(true);
        assert_eq!(modern(vec3(0.3, 0.0, -1.0)), 0.0, "Mitsuba 3: below the horizon is −z");
        assert!(modern(vec3(0.3, -1.0, 0.1)) > 0.0);
        assert!(!warnings.iter().any(|w| w.contains("sun")), "{warnings:?}");
        // Limb darkening: brighter than the uniform disk at the centre.
        assert!(modern(vec3(0.0, 1.0, 1.0)) > 1.1 * v3(false).0(vec3(0.0, 1.0, 1.0)));
    }
}
