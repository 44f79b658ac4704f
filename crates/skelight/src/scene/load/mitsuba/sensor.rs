//! Mitsuba's sensor (camera, film, reconstruction filter, sample count) and integrator
//! settings: what the render needs besides the scene's contents.

use roxmltree::Node;

use super::{Loader, R};
use crate::camera::{Camera, FovAxis, Lens};
use crate::film::Filter;
use crate::scene::RenderSettings;

impl Loader {
    pub(super) fn sensor(&mut self, n: Node) -> R<()> {
        let ty = self.attr(n, "type")?.unwrap_or_default();
        if ty != "perspective" && ty != "thinlens" {
            self.warn_at(n, format!("sensor '{ty}' is not supported; using a perspective camera"));
        }
        let to_world = self.transform(n, "to_world")?;
        let mut settings = RenderSettings {
            integrator: self.desc.settings.integrator.clone(),
            integrator_params: self.desc.settings.integrator_params.clone(),
            max_depth: self.desc.settings.max_depth,
            rr_depth: self.desc.settings.rr_depth,
            ..RenderSettings::default()
        };
        let film = n.children().find(|c| c.is_element() && c.tag_name().name() == "film");
        if let Some(f) = film {
            let w = self.int(f, "width", 768)?;
            let h = self.int(f, "height", 576)?;
            crate::scene::check_resolution(w, h).map_err(|m| self.err(f, m))?;
            settings.width = w as usize;
            settings.height = h as usize;
            if let Some(rf) = f.children().find(|c| c.is_element() && c.tag_name().name() == "rfilter") {
                settings.filter = match self.attr(rf, "type")?.as_deref().unwrap_or("gaussian") {
                    "box" => Filter::Box,
                    "tent" => Filter::Tent { radius: self.float(rf, "radius", 1.0)? },
                    "gaussian" => Filter::Gaussian { stddev: self.float(rf, "stddev", 0.5)? },
                    other => {
                        self.warn(format!(
                            "{}: reconstruction filter '{other}' is not supported; using gaussian",
                            self.file.display()
                        ));
                        Filter::Gaussian { stddev: 0.5 }
                    }
                };
            }
        }
        if let Some(s) = n.children().find(|c| c.is_element() && c.tag_name().name() == "sampler") {
            let spp = self.int(s, "sample_count", 4)?;
            if !(1..=1 << 24).contains(&spp) {
                return Err(self.err(s, format!("sample_count {spp} is out of range (1 to 2^24)")));
            }
            settings.spp = spp as u32;
        }
        let fov = match self.prop(n, "fov") {
            Some(_) => self.float(n, "fov", 45.0)?,
            None => match self.string(n, "focal_length")? {
                Some(fl) => {
                    let mm: f32 = fl
                        .trim_end_matches("mm")
                        .trim()
                        .parse()
                        .map_err(|_| self.err(n, format!("bad focal length '{fl}'")))?;
                    2.0 * (36.0 / (2.0 * mm)).atan().to_degrees()
                }
                None => 45.0,
            },
        };
        if !(fov > 0.0 && fov < 180.0) {
            return Err(self.err(n, format!("field of view {fov}° must lie in (0, 180)")));
        }
        let axis = match self.string(n, "fov_axis")?.as_deref().unwrap_or("x") {
            "x" => FovAxis::X,
            "y" => FovAxis::Y,
            "diagonal" => FovAxis::Diagonal,
            "smaller" => FovAxis::Smaller,
            "larger" => FovAxis::Larger,
            other => return Err(self.err(n, format!("unknown fov_axis '{other}'"))),
        };
        self.fov = (fov, axis);
        let aperture = if ty == "thinlens" { self.float(n, "aperture_radius", 0.03)? } else { 0.0 };
        let focus = self.float(n, "focus_distance", 0.0)?;
        // (Floats are finite once parsed.)
        if aperture < 0.0 {
            return Err(self.err(n, format!("thinlens aperture_radius {aperture} must be at least 0")));
        }
        if aperture > 0.0 && !(focus > 0.0) {
            return Err(self.err(n, "thinlens needs a positive focus_distance"));
        }
        let near = self.float(n, "near_clip", Camera::DEFAULT_NEAR_CLIP)?.max(0.0);
        self.desc.camera = Some(Camera::new(
            to_world,
            settings.width,
            settings.height,
            fov,
            axis,
            Lens { aperture_radius: aperture, focus_distance: focus },
            near,
        ));
        self.desc.settings = settings;
        Ok(())
    }

    pub(super) fn integrator(&mut self, n: Node) -> R<()> {
        let ty = self.attr(n, "type")?.unwrap_or_default();
        // Wrappers (adaptive, irrcache…) nest the integrator that sets the depth.
        let mut node = n;
        while self.prop(node, "max_depth").is_none() {
            match node.children().find(|c| c.is_element() && c.tag_name().name() == "integrator") {
                Some(c) => node = c,
                None => break,
            }
        }
        // Properties other than the depths, for the estimator of the same name to read.
        let mut params = Vec::new();
        for c in node.children().filter(|c| c.is_element()) {
            if !matches!(c.tag_name().name(), "integer" | "float" | "boolean" | "string") {
                continue;
            }
            if let (Some(name), Some(value)) = (self.attr(c, "name")?, self.attr(c, "value")?) {
                if name != "max_depth" && name != "rr_depth" {
                    params.push((name, value));
                }
            }
        }
        let s = &mut self.desc.settings;
        s.integrator = ty;
        s.integrator_params = params;
        let (md, rr) = (self.int(node, "max_depth", -1)?, self.int(node, "rr_depth", 5)?);
        if md < -1 || rr < 0 {
            return Err(self.err(node, "max_depth must be ≥ -1 and rr_depth ≥ 0"));
        }
        let s = &mut self.desc.settings;
        s.max_depth = md.min(i32::MAX as i64) as i32;
        s.rr_depth = rr.min(u32::MAX as i64) as u32;
        Ok(())
    }
}
