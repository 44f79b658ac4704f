//! Mitsuba BSDF plugins read into our materials; nested BSDFs with an `id` are registered as
//! Mitsuba 0.x does, so a later `<ref>` finds them.

use roxmltree::Node;

use super::{Loader, MaterialRef, Parsed, R};
use crate::color::Rgb;
use crate::material::fresnel::named_conductor;
use crate::material::microfacet::{Microfacet, MicrofacetType};
use crate::material::*;
use crate::texture::Texture;

impl Loader {
    pub(super) fn material(&mut self, n: Node) -> R<MaterialRef> {
        let p = self.bsdf(n)?;
        let id = self.attr(n, "id")?.unwrap_or_else(|| format!("anonymous{}", self.desc.materials.len()));
        let index = self.desc.materials.len() as u32;
        self.desc.materials.push(Material { name: id, bsdf: p.bsdf, perturbation: p.perturbation });
        Ok(MaterialRef { index, alpha: p.alpha })
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
        self.bsdf(c)
    }

    fn distribution(&self, n: Node) -> R<Microfacet> {
        let kind = match self.string(n, "distribution")?.as_deref().unwrap_or("beckmann") {
            "beckmann" | "phong" => MicrofacetType::Beckmann,
            "ggx" => MicrofacetType::Ggx,
            other => return Err(self.err(n, format!("unknown microfacet distribution '{other}'"))),
        };
        let scalar = |name: &str, d: f32| -> R<f32> {
            match self.prop(n, name) {
                Some(p) if p.tag_name().name() == "texture" || p.tag_name().name() == "ref" => {
                    Ok(self.texture(n, name, Rgb::splat(d))?.mean().mean())
                }
                _ => self.float(n, name, d),
            }
        };
        let alpha = scalar("alpha", 0.1)?;
        Ok(Microfacet::new(kind, scalar("alpha_u", alpha)?, scalar("alpha_v", alpha)?))
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

    fn bsdf(&mut self, n: Node) -> R<Parsed> {
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
