//! Mitsuba BSDF plugins read into our materials; nested BSDFs with an `id` are registered as
//! Mitsuba 0.x does, so a later `<ref>` finds them.

use roxmltree::Node;

use super::{Loader, MaterialRef, Parsed, R};
use crate::color::Rgb;
use crate::material::fresnel::named_conductor;
use crate::material::microfacet::{Microfacet, MicrofacetType};
use crate::material::*;
use crate::texture::Texture;

/// Most BSDFs one material may be made of; real ones have a handful.
const MAX_BSDF_NODES: usize = 256;

impl Loader {
    pub(super) fn material(&mut self, n: Node) -> R<MaterialRef> {
        let p = self.bsdf(n)?;
        self.add_material(n, p)
    }

    /// Adds a parsed BSDF to the scene's materials; one with an `id` can then be referenced.
    fn add_material(&mut self, n: Node, p: Parsed) -> R<MaterialRef> {
        let id = self.attr(n, "id")?;
        let index = self.desc.materials.len() as u32;
        let name = id.clone().unwrap_or_else(|| format!("anonymous{index}"));
        self.desc.materials.push(Material { name, bsdf: p.bsdf, perturbation: p.perturbation });
        let m = MaterialRef { index, alpha: p.alpha };
        if let Some(id) = id {
            self.materials.insert(id, m.clone());
        }
        Ok(m)
    }

    fn nested_bsdfs<'a, 'i>(&self, n: Node<'a, 'i>) -> Vec<Node<'a, 'i>> {
        n.children()
            .filter(|c| {
                c.is_element()
                    && (c.tag_name().name() == "bsdf"
                        || (c.tag_name().name() == "ref" && c.attribute("name").is_none_or(|nm| nm.contains("bsdf"))))
            })
            .collect()
    }

    fn nested(&mut self, n: Node, k: usize) -> R<Parsed> {
        let kids = self.nested_bsdfs(n);
        let c = *kids.get(k).ok_or_else(|| self.err(n, "expected a nested <bsdf>"))?;
        if c.tag_name().name() == "ref" {
            let id = self.attr(c, "id")?.unwrap_or_default();
            let m = self.materials.get(&id).cloned().ok_or_else(|| self.err(c, format!("no bsdf with id '{id}'")))?;
            let mat = &self.desc.materials[m.index as usize];
            return Ok(Parsed { bsdf: mat.bsdf.clone(), perturbation: mat.perturbation.clone(), alpha: m.alpha });
        }
        let p = self.bsdf(c)?;
        // Mitsuba 0.x files refer to BSDFs nested in others (a bump map's inner BSDF) by id.
        if c.attribute("id").is_some() {
            self.add_material(c, p.clone())?;
        }
        Ok(p)
    }

    fn distribution(&self, n: Node) -> R<Microfacet> {
        let kind = match self.string(n, "distribution")?.as_deref().unwrap_or("beckmann") {
            "beckmann" | "phong" => MicrofacetType::Beckmann,
            "ggx" => MicrofacetType::Ggx,
            other => return Err(self.err(n, format!("unknown microfacet distribution '{other}'"))),
        };
        let alpha = self.scalar(n, "alpha", 0.1)?;
        Ok(Microfacet::new(kind, self.scalar(n, "alpha_u", alpha)?, self.scalar(n, "alpha_v", alpha)?))
    }

    /// A number, or the mean of a texture where one is given (roughness maps).
    fn scalar(&self, n: Node, name: &str, default: f32) -> R<f32> {
        match self.prop(n, name) {
            Some(p) if p.tag_name().name() == "texture" || p.tag_name().name() == "ref" => {
                Ok(self.texture(n, name, Rgb::splat(default))?.mean().mean())
            }
            _ => self.float(n, name, default),
        }
    }

    /// Mitsuba 0.x's `ward` (0.4 and earlier named the variant `type` and the roughnesses
    /// `alphaX`, `alphaY`).
    fn ward(&self, n: Node) -> R<Ward> {
        let name = match self.string(n, "variant")? {
            Some(v) => v,
            None => self.string(n, "type")?.unwrap_or_else(|| "balanced".into()),
        };
        let variant = WardVariant::from_name(&name)
            .ok_or_else(|| self.err(n, format!("ward: unknown variant '{name}' (ward, ward-duer or balanced)")))?;
        let alpha = self.scalar(n, "alpha", 0.1)?;
        let alpha_u = self.scalar(n, "alpha_u", self.scalar(n, "alpha_x", alpha)?)?;
        let alpha_v = self.scalar(n, "alpha_v", self.scalar(n, "alpha_y", alpha)?)?;
        if !(alpha_u > 0.0 && alpha_v > 0.0) {
            return Err(self.err(n, format!("ward: alpha_u {alpha_u} and alpha_v {alpha_v} must be positive")));
        }
        let diffuse = self.texture(n, "diffuse_reflectance", Rgb::splat(0.5))?;
        let specular = self.texture(n, "specular_reflectance", Rgb::splat(0.2))?;
        Ok(Ward::new(variant, alpha_u, alpha_v, diffuse, specular))
    }

    fn eta(&self, n: Node, int_default: f32) -> R<f32> {
        let int = self.float(n, "int_ior", int_default)?;
        let ext = self.float(n, "ext_ior", 1.000277)?;
        if !(int > 0.0 && ext > 0.0) {
            return Err(self.err(n, "indices of refraction must be positive"));
        }
        Ok(int / ext)
    }

    fn conductor_ior(&self, n: Node) -> R<(Rgb, Rgb)> {
        let name = self.string(n, "material")?.unwrap_or_else(|| "none".into());
        let (eta, k) = named_conductor(&name).ok_or_else(|| self.err(n, format!("unknown conductor '{name}'")))?;
        let ext = self.float(n, "ext_eta", 1.0)?;
        let eta = self.color(n, "eta", eta)?;
        let k = self.color(n, "k", k)?;
        Ok((eta / ext, k / ext))
    }

    /// A `<bsdf>` element, refused when `<ref>`s make it grow past [`MAX_BSDF_NODES`]: a
    /// chain of two-sided BSDFs, each referring to the previous one, doubles at each link.
    fn bsdf(&mut self, n: Node) -> R<Parsed> {
        let p = self.bsdf_of_type(n)?;
        if p.bsdf.node_count() > MAX_BSDF_NODES {
            return Err(self.err(n, format!("this BSDF is made of more than {MAX_BSDF_NODES} BSDFs (through <ref>s)")));
        }
        Ok(p)
    }

    fn bsdf_of_type(&mut self, n: Node) -> R<Parsed> {
        let ty = self.attr(n, "type")?.unwrap_or_default();
        let plain = |bsdf: Bsdf| Ok(Parsed { bsdf, perturbation: None, alpha: None });
        match ty.as_str() {
            "diffuse" | "lambertian" => {
                plain(Bsdf::Diffuse(Diffuse { reflectance: self.texture(n, "reflectance", Rgb::splat(0.5))? }))
            }
            "roughdiffuse" => plain(Bsdf::RoughDiffuse(RoughDiffuse {
                reflectance: self.texture(n, "reflectance", Rgb::splat(0.5))?,
                alpha: self.float(n, "alpha", 0.2)?,
            })),
            "conductor" => {
                let (eta, k) = self.conductor_ior(n)?;
                plain(Bsdf::Conductor(Conductor {
                    eta,
                    k,
                    specular_reflectance: self.texture(n, "specular_reflectance", Rgb::WHITE)?,
                }))
            }
            "roughconductor" => {
                let (eta, k) = self.conductor_ior(n)?;
                plain(Bsdf::RoughConductor(RoughConductor {
                    distribution: self.distribution(n)?,
                    eta,
                    k,
                    specular_reflectance: self.texture(n, "specular_reflectance", Rgb::WHITE)?,
                }))
            }
            "dielectric" => plain(Bsdf::Dielectric(Dielectric {
                eta: self.eta(n, 1.5046)?,
                specular_reflectance: self.color(n, "specular_reflectance", Rgb::WHITE)?,
                specular_transmittance: self.color(n, "specular_transmittance", Rgb::WHITE)?,
            })),
            "thindielectric" => plain(Bsdf::ThinDielectric(ThinDielectric {
                eta: self.eta(n, 1.5046)?,
                specular_reflectance: self.color(n, "specular_reflectance", Rgb::WHITE)?,
                specular_transmittance: self.color(n, "specular_transmittance", Rgb::WHITE)?,
            })),
            "roughdielectric" => plain(Bsdf::RoughDielectric(RoughDielectric {
                distribution: self.distribution(n)?,
                eta: self.eta(n, 1.5046)?,
                specular_reflectance: self.color(n, "specular_reflectance", Rgb::WHITE)?,
                specular_transmittance: self.color(n, "specular_transmittance", Rgb::WHITE)?,
            })),
            "plastic" => plain(Bsdf::Plastic(Plastic::new(
                self.texture(n, "diffuse_reflectance", Rgb::splat(0.5))?,
                self.texture(n, "specular_reflectance", Rgb::WHITE)?,
                self.eta(n, 1.49)?,
                self.boolean(n, "nonlinear", false)?,
            ))),
            "roughplastic" => plain(Bsdf::RoughPlastic(RoughPlastic::new(
                self.distribution(n)?,
                self.texture(n, "diffuse_reflectance", Rgb::splat(0.5))?,
                self.texture(n, "specular_reflectance", Rgb::WHITE)?,
                self.eta(n, 1.49)?,
                self.boolean(n, "nonlinear", false)?,
            ))),
            "phong" => plain(Bsdf::Phong(Phong::new(
                self.texture(n, "diffuse_reflectance", Rgb::splat(0.5))?,
                self.texture(n, "specular_reflectance", Rgb::splat(0.2))?,
                self.float(n, "exponent", 30.0)?,
            ))),
            "ward" => plain(Bsdf::Ward(self.ward(n)?)),
            "coating" | "roughcoating" => {
                if ty == "roughcoating" {
                    self.warn(format!("{}: roughcoating is rendered as a smooth coating", self.file.display()));
                }
                let inner = self.nested(n, 0)?;
                let sigma = self.color(n, "sigma_a", Rgb::BLACK)? * self.float(n, "thickness", 1.0)?;
                Ok(Parsed {
                    bsdf: Bsdf::Coating(Coating::new(
                        self.eta(n, 1.5046)?,
                        self.color(n, "specular_reflectance", Rgb::WHITE)?,
                        sigma,
                        inner.bsdf,
                    )),
                    ..inner
                })
            }
            "twosided" => {
                let front = self.nested(n, 0)?;
                let back = if self.nested_bsdfs(n).len() > 1 { self.nested(n, 1)?.bsdf } else { front.bsdf.clone() };
                Ok(Parsed { bsdf: Bsdf::TwoSided(Box::new(front.bsdf), Box::new(back)), ..front })
            }
            "mask" => {
                let opacity = self.texture(n, "opacity", Rgb::splat(0.5))?;
                let inner = self.nested(n, 0)?;
                Ok(Parsed { alpha: Some(opacity), ..inner })
            }
            "bump" | "bumpmap" => {
                let tex = n
                    .children()
                    .find(|c| c.is_element() && c.tag_name().name() == "texture")
                    .ok_or_else(|| self.err(n, "bump needs a <texture>"))?;
                let height = self.texture_node(tex)?;
                let scale = self.float(n, "scale", 1.0)?;
                let inner = self.nested(n, 0)?;
                Ok(Parsed { perturbation: Some(Perturbation::Bump { height, scale }), ..inner })
            }
            "normalmap" => {
                let normals = match self.prop(n, "normalmap") {
                    Some(_) => self.texture(n, "normalmap", Rgb::splat(0.5))?,
                    None => {
                        let tex = n
                            .children()
                            .find(|c| c.is_element() && c.tag_name().name() == "texture")
                            .ok_or_else(|| self.err(n, "normalmap needs a <texture>"))?;
                        self.texture_node(tex)?
                    }
                };
                let inner = self.nested(n, 0)?;
                Ok(Parsed { perturbation: Some(Perturbation::NormalMap { normals }), ..inner })
            }
            "null" => Ok(Parsed { bsdf: Bsdf::Black, perturbation: None, alpha: Some(Texture::constant(0.0)) }),
            other => {
                self.warn_at(n, format!("BSDF type '{other}' is not supported; rendered as magenta diffuse"));
                plain(Material::fallback(other).bsdf)
            }
        }
    }

    pub(super) fn default_material(&mut self, emitter: bool) -> u32 {
        let slot = emitter as usize;
        if let Some(i) = self.default_materials[slot] {
            return i;
        }
        let i = self.desc.materials.len() as u32;
        let (name, value) = if emitter { ("default-emitter", 0.0) } else { ("default", 0.5) };
        self.desc.materials.push(Material::new(name, Bsdf::Diffuse(Diffuse { reflectance: Texture::constant(value) })));
        self.default_materials[slot] = Some(i);
        i
    }
}

#[cfg(test)]
mod tests {
    use crate::material::{Bsdf, WardVariant};

    fn first_bsdf(name: &str, bsdf: &str) -> Result<Bsdf, String> {
        let dir = std::env::temp_dir().join(format!("skelight-mitsuba-bsdf-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("s.xml");
        std::fs::write(&path, format!(r#"<scene version="0.6.0"><shape type="rectangle">{bsdf}</shape></scene>"#))
            .unwrap();
        let scene = crate::scene::load::load(&path, &[]).map_err(|e| e.to_string());
        let _ = std::fs::remove_dir_all(&dir);
        let scene = scene?;
        Ok(scene.materials[scene.meshes[0].material as usize].bsdf.clone())
    }

    /// Mitsuba 0.6's names and defaults; reflectances summing past 1 are scaled down.
    #[test]
    fn ward_reads_mitsuba_parameters() {
        let Bsdf::Ward(w) = first_bsdf("ward", r#"<bsdf type="ward"/>"#).unwrap() else { panic!("not ward") };
        assert_eq!((w.variant, w.alpha_u, w.alpha_v), (WardVariant::Balanced, 0.1, 0.1));
        assert_eq!((w.diffuse.mean().g, w.specular.mean().g), (0.5, 0.2));
        let xml = r#"<bsdf type="ward"><string name="variant" value="ward-duer"/><float name="alphaU" value="0.2"/>
            <float name="alphaV" value="0.4"/><spectrum name="specularReflectance" value="0.9"/>
            <rgb name="diffuseReflectance" value="0.3"/></bsdf>"#;
        let Bsdf::Ward(w) = first_bsdf("duer", xml).unwrap() else { panic!("not ward") };
        assert_eq!((w.variant, w.alpha_u, w.alpha_v), (WardVariant::WardDuer, 0.2, 0.4));
        assert!((w.diffuse.mean().g + w.specular.mean().g - 1.0).abs() < 1e-6, "scaled to a sum of 1");
        let e = first_bsdf("bad", r#"<bsdf type="ward"><string name="variant" value="blinn"/></bsdf>"#).unwrap_err();
        assert!(e.contains("s.xml:") && e.contains("unknown variant 'blinn'"), "{e}");
        let e = first_bsdf("zero", r#"<bsdf type="ward"><float name="alphaU" value="0"/></bsdf>"#).unwrap_err();
        assert!(e.contains("must be positive"), "{e}");
    }
}
