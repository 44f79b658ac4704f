//! The kernels' `data` buffer: textures (a descriptor each, then the texels of every bitmap
//! once, linear RGB as the CPU decoded them), BSDF tables (rough plastics' transmittance) and
//! an environment map's texels and sampling distributions, addressed by word offsets that
//! materials and the parameters carry. Layouts match texture.wgsl and environment.wgsl.

use std::collections::HashMap;
use std::sync::Arc;

use skelight::color::Rgb;
use skelight::light::EnvMap;
use skelight::math::vec3;
use skelight::texture::{Bitmap, TexFilter, Texture, UvTransform};

/// Texture kinds (texture.wgsl).
pub const TEX_BILINEAR: u32 = 0;
pub const TEX_NEAREST: u32 = 1;
pub const TEX_CHECKER: u32 = 2;

/// Words of a texture descriptor: kind, width, height, texel offset, the uv transform (6),
/// scale, colour 0 and colour 1 of a checkerboard.
pub const DESCRIPTOR_WORDS: usize = 17;

/// The data buffer being filled, with each bitmap's texels stored once.
#[derive(Default)]
pub struct Tables {
    pub data: Vec<f32>,
    texels: HashMap<*const Bitmap, u32>,
}

impl Tables {
    /// Appends `values` and returns their offset.
    pub fn push(&mut self, values: &[f32]) -> u32 {
        let at = self.data.len() as u32;
        self.data.extend_from_slice(values);
        at
    }

    /// The descriptor of a non-constant texture (its offset), `None` for a constant one.
    /// Scales fold into the descriptor; a scaled constant stays constant (the caller reads
    /// it with [`constant_value`]).
    pub fn texture(&mut self, t: &Texture) -> Option<u32> {
        let mut scale = 1.0;
        let mut t = t;
        while let Texture::Scale { scale: s, inner } = t {
            scale *= *s;
            t = inner;
        }
        let mut words = [0.0f32; DESCRIPTOR_WORDS];
        let word = |u: u32| f32::from_bits(u);
        match t {
            Texture::Constant(_) | Texture::Scale { .. } => return None,
            Texture::Bitmap { bitmap, to_uv } => {
                let texels = self.texels(bitmap);
                let kind = if bitmap.filter == TexFilter::Nearest { TEX_NEAREST } else { TEX_BILINEAR };
                words[..4].copy_from_slice(&[
                    word(kind),
                    word(bitmap.image.width as u32),
                    word(bitmap.image.height as u32),
                    word(texels),
                ]);
                words[4..10].copy_from_slice(&to_uv.m);
            }
            Texture::Checkerboard { color0, color1, to_uv } => {
                words[0] = word(TEX_CHECKER);
                words[4..10].copy_from_slice(&to_uv.m);
                words[11..14].copy_from_slice(&[color0.r, color0.g, color0.b]);
                words[14..17].copy_from_slice(&[color1.r, color1.g, color1.b]);
            }
        }
        words[10] = scale;
        Some(self.push(&words))
    }

    /// A constant as a texture descriptor (a checkerboard of one colour), where a kernel
    /// reads a texture unconditionally (opacity masks).
    pub fn constant_texture(&mut self, value: Option<[f32; 3]>) -> u32 {
        let [r, g, b] = value.unwrap_or([1.0; 3]);
        let c = Rgb { r, g, b };
        let one_colour = Texture::Checkerboard { color0: c, color1: c, to_uv: UvTransform::IDENTITY };
        self.texture(&one_colour).expect("a checkerboard has a descriptor")
    }

    fn texels(&mut self, bitmap: &Arc<Bitmap>) -> u32 {
        if let Some(&at) = self.texels.get(&Arc::as_ptr(bitmap)) {
            return at;
        }
        let flat: Vec<f32> = bitmap.image.pixels.iter().flat_map(|p| [p.r, p.g, p.b]).collect();
        let at = self.push(&flat);
        self.texels.insert(Arc::as_ptr(bitmap), at);
        at
    }
}

/// Words of an environment map's descriptor (environment.wgsl): width, height, rows of
/// cells, texel offset, scale, to_world's and to_local's columns (9 each), the marginal's and
/// the conditionals' cumulative tables' offsets.
pub const ENVIRONMENT_WORDS: usize = 25;

impl Tables {
    /// An environment map's descriptor, texels and sampling tables (its offset): the CPU's
    /// own distribution (EnvMap::new: cells between texel rows), its marginal over rows and a
    /// conditional per row as cumulative tables (n + 1 words each, from 0 to 1).
    pub fn environment_map(&mut self, env: &EnvMap) -> u32 {
        let image = env.image();
        let distribution = env.distribution();
        let rows = distribution.conditionals().len();
        let texels: Vec<f32> = image.pixels.iter().flat_map(|p| [p.r, p.g, p.b]).collect();
        let texels = self.push(&texels);
        let marginal = self.push(distribution.marginal().cdf());
        let conditional = self.data.len() as u32;
        for row in distribution.conditionals() {
            self.push(row.cdf());
        }
        let word = |u: u32| f32::from_bits(u);
        let columns = |f: &dyn Fn(skelight::math::Vec3) -> skelight::math::Vec3| {
            [vec3(1.0, 0.0, 0.0), vec3(0.0, 1.0, 0.0), vec3(0.0, 0.0, 1.0)].map(f).map(|v| [v.x, v.y, v.z]).concat()
        };
        let to_world = env.to_world();
        let to_local = to_world.inverse();
        let mut words =
            vec![word(image.width as u32), word(image.height as u32), word(rows as u32), word(texels), env.scale()];
        words.extend(columns(&|v| to_world.vector(v)));
        words.extend(columns(&|v| to_local.vector(v)));
        words.extend([word(marginal), word(conditional)]);
        debug_assert_eq!(words.len(), ENVIRONMENT_WORDS);
        self.push(&words)
    }
}

/// A constant texture's value (scales applied), or `None` for any other.
pub fn constant_value(t: &Texture) -> Option<[f32; 3]> {
    match t {
        Texture::Constant(c) => Some([c.r, c.g, c.b]),
        Texture::Scale { scale, inner } => constant_value(inner).map(|c| c.map(|v| v * scale)),
        _ => None,
    }
}
