//! Reading and writing images: OpenEXR (scan-line, 32-bit float) and PNG/JPEG.
//! Outputs are written to a temporary name and renamed, so no reader sees half a file.

use std::path::{Path, PathBuf};

use crate::boundary::catch_panic;
use crate::color::{linear_to_srgb, rgb, Rgb};

/// A linear RGB image, row-major, top row first.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<Rgb>,
}

#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    #[error("{path}: cannot read image: {reason}")]
    Read { path: PathBuf, reason: String },
    #[error("{path}: cannot write image: {reason}")]
    Write { path: PathBuf, reason: String },
}

impl Image {
    pub fn new(width: usize, height: usize) -> Image {
        Image { width, height, pixels: vec![Rgb::BLACK; width * height] }
    }
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> Rgb {
        self.pixels[y * self.width + x]
    }
    pub fn mean(&self) -> Rgb {
        let n = self.pixels.len().max(1) as f64;
        let s = self.pixels.iter().fold([0.0f64; 3], |a, p| [a[0] + p.r as f64, a[1] + p.g as f64, a[2] + p.b as f64]);
        Rgb::from_array(s.map(|v| (v / n) as f32))
    }

    /// How many pixels have a NaN or infinite channel, and where the first one is.
    pub fn non_finite(&self) -> Option<(usize, (usize, usize))> {
        let first = self.pixels.iter().position(|p| !p.is_finite())?;
        let count = self.pixels.iter().filter(|p| !p.is_finite()).count();
        Some((count, (first % self.width, first / self.width)))
    }

    /// Loads EXR, PNG or JPEG by extension. Values are returned as stored (no sRGB decoding).
    pub fn load(path: &Path) -> Result<Image, ImageError> {
        let err = |reason: String| ImageError::Read { path: path.to_path_buf(), reason };
        if !path.exists() {
            return Err(err("file not found".into()));
        }
        let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
        if ext == "exr" {
            return load_exr(path).map(|(img, _)| img).map_err(err);
        }
        let img = decode_image(path).map_err(err)?;
        let rgb32 = img.to_rgb32f();
        let (w, h) = (rgb32.width() as usize, rgb32.height() as usize);
        if w == 0 || h == 0 {
            return Err(err("image has no pixels".into()));
        }
        let pixels = rgb32.pixels().map(|p| rgb(p.0[0], p.0[1], p.0[2])).collect();
        Ok(Image { width: w, height: h, pixels })
    }

    /// Alpha channel (or luminance for images without one), as stored, for opacity masks.
    pub fn load_alpha_or_luminance(path: &Path) -> Result<Image, ImageError> {
        let err = |reason: String| ImageError::Read { path: path.to_path_buf(), reason };
        let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
        if ext == "exr" {
            return Image::load(path);
        }
        let img = decode_image(path).map_err(err)?;
        if !img.color().has_alpha() {
            return Image::load(path);
        }
        let rgba = img.to_rgba32f();
        let (w, h) = (rgba.width() as usize, rgba.height() as usize);
        let pixels = rgba.pixels().map(|p| Rgb::splat(p.0[3])).collect();
        Ok(Image { width: w, height: h, pixels })
    }

    /// Writes a scan-line float EXR atomically.
    pub fn save_exr(&self, path: &Path) -> Result<(), ImageError> {
        self.save_exr_with(path, &[])
    }

    /// Writes a scan-line float EXR atomically, with numeric header attributes
    /// (`skelight.spp` records how many samples per pixel the image holds).
    pub fn save_exr_with(&self, path: &Path, attributes: &[(&str, f64)]) -> Result<(), ImageError> {
        use exr::prelude::*;
        let err = |reason: String| ImageError::Write { path: path.to_path_buf(), reason };
        let channels = SpecificChannels::rgb(|p: Vec2<usize>| {
            let c = self.pixels[p.1 * self.width + p.0];
            (c.r, c.g, c.b)
        });
        let mut attrs = LayerAttributes::named("rgb");
        for (k, v) in attributes {
            attrs.other.insert(Text::from(*k), AttributeValue::F64(*v));
        }
        let layer = Layer::new((self.width, self.height), attrs, Encoding::SMALL_LOSSLESS, channels);
        let image = exr::image::Image::from_layer(layer);
        write_atomically(path, |tmp| image.write().to_file(tmp).map_err(|e| e.to_string())).map_err(err)
    }

    /// Writes an EXR whose header also carries text and binary attributes (a shard's
    /// manifest and its film), atomically.
    pub fn save_exr_annotated(&self, path: &Path, notes: &Annotations) -> Result<(), ImageError> {
        use exr::prelude::*;
        let err = |reason: String| ImageError::Write { path: path.to_path_buf(), reason };
        let channels = SpecificChannels::rgb(|p: Vec2<usize>| {
            let c = self.pixels[p.1 * self.width + p.0];
            (c.r, c.g, c.b)
        });
        let mut attrs = LayerAttributes::named("rgb");
        for (k, v) in &notes.numbers {
            attrs.other.insert(Text::from(k.as_str()), AttributeValue::F64(*v));
        }
        for (k, v) in &notes.texts {
            let text = Text::new_or_none(v.as_str()).ok_or_else(|| err(format!("attribute {k} is not plain text")))?;
            attrs.other.insert(Text::from(k.as_str()), AttributeValue::Text(text));
        }
        for (k, v) in &notes.blobs {
            let bytes = exr::prelude::SmallVec::from_vec(v.clone());
            attrs.other.insert(Text::from(k.as_str()), AttributeValue::Custom { kind: Text::from(BLOB_KIND), bytes });
        }
        let layer = Layer::new((self.width, self.height), attrs, Encoding::SMALL_LOSSLESS, channels);
        let image = exr::image::Image::from_layer(layer);
        write_atomically(path, |tmp| image.write().to_file(tmp).map_err(|e| e.to_string())).map_err(err)
    }

    /// Loads an EXR with all its header attributes: numbers, texts and binary blobs.
    pub fn load_exr_annotated(path: &Path) -> Result<(Image, Annotations), ImageError> {
        let err = |reason: String| ImageError::Read { path: path.to_path_buf(), reason };
        if !path.exists() {
            return Err(err("file not found".into()));
        }
        check_exr_header(path).map_err(err)?;
        catch_panic("EXR data", || decode_exr(path)).and_then(|r| r).map_err(err)
    }

    /// Loads an EXR with its numeric header attributes.
    pub fn load_exr_with_attributes(path: &Path) -> Result<(Image, Vec<(String, f64)>), ImageError> {
        let err = |reason: String| ImageError::Read { path: path.to_path_buf(), reason };
        if !path.exists() {
            return Err(err("file not found".into()));
        }
        load_exr(path).map_err(err)
    }

    /// 8-bit sRGB PNG bytes after multiplying by `2^exposure` (non-finite values as black).
    pub fn to_png_bytes(&self, exposure: f32) -> Result<Vec<u8>, String> {
        let scale = 2f32.powf(exposure);
        let mut buf = Vec::with_capacity(self.pixels.len() * 3);
        for p in &self.pixels {
            for v in p.to_array() {
                let v = if v.is_finite() { v * scale } else { 0.0 };
                buf.push((linear_to_srgb(v) * 255.0 + 0.5) as u8);
            }
        }
        let mut out = std::io::Cursor::new(Vec::new());
        image::write_buffer_with_format(
            &mut out,
            &buf,
            self.width as u32,
            self.height as u32,
            image::ExtendedColorType::Rgb8,
            image::ImageFormat::Png,
        )
        .map_err(|e| e.to_string())?;
        Ok(out.into_inner())
    }

    /// Writes an 8-bit sRGB PNG after multiplying by `2^exposure`, atomically.
    pub fn save_png(&self, path: &Path, exposure: f32) -> Result<(), ImageError> {
        let err = |reason: String| ImageError::Write { path: path.to_path_buf(), reason };
        let bytes = self.to_png_bytes(exposure).map_err(err)?;
        write_atomically(path, |tmp| std::fs::write(tmp, &bytes).map_err(|e| e.to_string())).map_err(err)
    }

    /// Saves by extension (.exr or .png).
    pub fn save(&self, path: &Path) -> Result<(), ImageError> {
        match path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase()).as_deref() {
            Some("png") => self.save_png(path, 0.0),
            _ => self.save_exr(path),
        }
    }
}

/// Decodes a PNG or JPEG file (the `image` crate bounds its allocations itself).
fn decode_image(path: &Path) -> Result<image::DynamicImage, String> {
    catch_panic("image data", || {
        image::ImageReader::open(path)
            .map_err(|e| e.to_string())?
            .with_guessed_format()
            .map_err(|e| e.to_string())?
            .decode()
            .map_err(|e| e.to_string())
    })?
}

/// Where a render's image goes: the OpenEXR file and the tone-mapped PNG beside it. `x.exr`
/// and `x` give `x.exr` and `x.png`; `x.png` gives the same two, so that naming the PNG never
/// loses the HDR image under it. Any other extension is refused: an output named like the
/// scene (`-o scene.xml`) would replace an input.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageOutput {
    pub exr: PathBuf,
    pub png: PathBuf,
}

impl ImageOutput {
    pub fn of(path: &Path) -> Result<ImageOutput, ImageError> {
        let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase());
        match ext.as_deref() {
            None | Some("exr") | Some("png") => {
                let exr = if ext.as_deref() == Some("exr") { path.to_path_buf() } else { path.with_extension("exr") };
                Ok(ImageOutput { png: exr.with_extension("png"), exr })
            }
            Some(other) => Err(ImageError::Write {
                path: path.to_path_buf(),
                reason: format!(
                    "an image output is named .exr (a PNG is written beside it) or .png (the EXR is written \
                     beside it), not .{other}"
                ),
            }),
        }
    }
}

/// The file a write to `path` lands on: `path` itself, or the file a link at `path` points to
/// (written through, the link kept). Refuses a target that exists and is not a regular file
/// (a device node, a FIFO, a folder) and a link to nothing: renaming a temporary file over
/// them would destroy what is there.
pub fn write_target(path: &Path) -> Result<PathBuf, String> {
    let link = std::fs::symlink_metadata(path).map(|m| m.file_type().is_symlink()).unwrap_or(false);
    let target = if link {
        path.canonicalize().map_err(|e| format!("is a link to a file that cannot be reached ({e})"))?
    } else {
        path.to_path_buf()
    };
    match std::fs::metadata(&target) {
        Ok(m) if !m.is_file() => Err(format!(
            "{}exists and is not a regular file (a device, a FIFO or a folder): skelight writes only regular \
             files; choose another output",
            if link { format!("its link target {} ", target.display()) } else { String::new() }
        )),
        _ => Ok(target),
    }
}

/// Runs `write` on a temporary file beside `path`, then renames it into place (see
/// [`write_target`] for what `path` may be).
pub fn write_atomically(path: &Path, write: impl FnOnce(&Path) -> Result<(), String>) -> Result<(), String> {
    let path = &write_target(path)?;
    let dir = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    if !dir.exists() {
        std::fs::create_dir_all(dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    }
    let name = path.file_name().ok_or("not a file name")?.to_string_lossy().to_string();
    let ext = path.extension().map(|e| e.to_string_lossy().to_string()).unwrap_or_default();
    // Keep the extension last: some writers pick the format from it.
    let tmp = dir.join(format!(".{name}.{}.tmp.{ext}", std::process::id()));
    match write(&tmp) {
        Ok(()) => std::fs::rename(&tmp, path).map_err(|e| {
            let _ = std::fs::remove_file(&tmp);
            e.to_string()
        }),
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            Err(e)
        }
    }
}

/// Writes `bytes` to `path` through a temporary file (see [`write_atomically`]).
pub fn write_file_atomically(path: &Path, bytes: &[u8]) -> Result<(), String> {
    write_atomically(path, |tmp| std::fs::write(tmp, bytes).map_err(|e| e.to_string()))
}

/// Most pixels an image may have (as many as the largest film).
pub const MAX_PIXELS: usize = 1 << 28;

/// Refuses an EXR whose layers claim more pixels than its size can hold before anything is
/// allocated for them: even compressed, a pixel takes a byte in at most ~1000.
fn check_exr_header(path: &Path) -> Result<(), String> {
    let file_len = std::fs::metadata(path).map_err(|e| e.to_string())?.len() as usize;
    let meta = exr::meta::MetaData::read_from_file(path, false).map_err(|e| e.to_string())?;
    for h in meta.headers.iter() {
        let (w, hgt) = (h.layer_size.0, h.layer_size.1);
        let pixels = w.saturating_mul(hgt);
        if pixels > MAX_PIXELS || pixels / 1024 > file_len {
            return Err(format!(
                "its data window of {w}×{hgt} pixels is more than a {file_len}-byte file can hold (or over 2^28 pixels)"
            ));
        }
    }
    Ok(())
}

/// Header attributes beside the pixels: numbers (`skelight.spp`), texts (a shard's
/// manifest) and binary blobs (a shard's film).
#[derive(Clone, Debug, Default)]
pub struct Annotations {
    pub numbers: Vec<(String, f64)>,
    pub texts: Vec<(String, String)>,
    pub blobs: Vec<(String, Vec<u8>)>,
}

impl Annotations {
    pub fn number(&self, key: &str) -> Option<f64> {
        self.numbers.iter().find(|(k, _)| k == key).map(|(_, v)| *v)
    }
    pub fn text(&self, key: &str) -> Option<&str> {
        self.texts.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str())
    }
    pub fn blob(&self, key: &str) -> Option<&[u8]> {
        self.blobs.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_slice())
    }
}

/// The EXR attribute type name of skelight's binary attributes.
const BLOB_KIND: &str = "skelightBytes";

fn load_exr(path: &Path) -> Result<(Image, Vec<(String, f64)>), String> {
    check_exr_header(path)?;
    catch_panic("EXR data", || decode_exr(path))?.map(|(img, notes)| (img, notes.numbers))
}

fn decode_exr(path: &Path) -> Result<(Image, Annotations), String> {
    use exr::prelude::*;
    let img = read_first_rgba_layer_from_file(
        path,
        |res: Vec2<usize>, _| crate::imageio::Image::new(res.0, res.1),
        |img: &mut crate::imageio::Image, pos: Vec2<usize>, (r, g, b, _a): (f32, f32, f32, f32)| {
            let w = img.width;
            img.pixels[pos.1 * w + pos.0] = rgb(r, g, b);
        },
    )
    .map_err(|e| e.to_string())?;
    let mut attributes = Annotations::default();
    for (k, v) in img.layer_data.attributes.other.iter() {
        let key = k.to_string();
        match v {
            AttributeValue::F64(x) => attributes.numbers.push((key, *x)),
            AttributeValue::F32(x) => attributes.numbers.push((key, *x as f64)),
            AttributeValue::I32(x) => attributes.numbers.push((key, *x as f64)),
            AttributeValue::Text(t) => attributes.texts.push((key, t.to_string())),
            AttributeValue::Custom { kind, bytes } if kind == BLOB_KIND => attributes.blobs.push((key, bytes.to_vec())),
            _ => {}
        }
    }
    let image: crate::imageio::Image = img.layer_data.channel_data.pixels;
    if image.width == 0 || image.height == 0 {
        return Err("image has no pixels".into());
    }
    Ok((image, attributes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exr_round_trip_and_png_written() {
        let dir = std::env::temp_dir().join(format!("skelight-imageio-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut img = Image::new(3, 2);
        for (i, p) in img.pixels.iter_mut().enumerate() {
            *p = rgb(i as f32, 0.5 * i as f32, 100.0);
        }
        let exr = dir.join("a.exr");
        img.save_exr_with(&exr, &[("skelight.spp", 64.0)]).unwrap();
        assert_eq!(Image::load(&exr).unwrap(), img);
        let (back, attrs) = Image::load_exr_with_attributes(&exr).unwrap();
        assert_eq!(back, img);
        assert!(attrs.iter().any(|(k, v)| k == "skelight.spp" && *v == 64.0), "{attrs:?}");
        let png = dir.join("a.png");
        img.save_png(&png, 0.0).unwrap();
        let back = Image::load(&png).unwrap();
        assert_eq!((back.width, back.height), (3, 2));
        // No temporary files are left behind.
        let leftovers = std::fs::read_dir(&dir)
            .unwrap()
            .filter(|e| e.as_ref().unwrap().file_name().to_string_lossy().contains(".tmp"));
        assert_eq!(leftovers.count(), 0);
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn missing_and_corrupt_files_are_errors() {
        let dir = std::env::temp_dir().join(format!("skelight-imageio-bad-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let e = Image::load(&dir.join("nope.png")).unwrap_err().to_string();
        assert!(e.contains("nope.png") && e.contains("not found"), "{e}");
        let bad = dir.join("bad.exr");
        std::fs::write(&bad, b"not an exr").unwrap();
        assert!(Image::load(&bad).unwrap_err().to_string().contains("bad.exr"));
        std::fs::remove_dir_all(&dir).ok();
    }
}
