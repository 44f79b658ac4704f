//! How the megakernels are launched: tiles, samples per dispatch, workgroups, threads per
//! pixel (slices), and whether instant BPT's two passes run as one kernel, each default
//! chosen by measurement on an H200 (docs/benchmarks.md).

use crate::bvh::Traversal;
use crate::GpuError;

/// Samples per pixel summed on the device (in f32) before the film takes them (in f64).
pub(crate) const READBACK_BATCH: u32 = 16;
/// Samples per pixel a dispatch takes at most on a GPU: long enough to amortise a dispatch,
/// short enough for drivers' watchdogs, and few enough for f32 sums (the film adds them in
/// f64).
const SAMPLES_PER_DISPATCH: u32 = 16;
/// The same on a CPU adapter (lavapipe): one. llvmpipe ends any shader loop after 65535
/// iterations, counted across the calls of a thread rather than per call, so the BVH
/// traversal of a thread's 15th light path through c09's glass ball already stopped early
/// (a 10 % dark image at 16 samples per dispatch, exact at 4).
const SAMPLES_PER_DISPATCH_CPU: u32 = 1;
/// Pixels along a tile's side: any resolution fits any device's dispatch limits.
const TILE: u32 = 512;
/// Threads of a workgroup along x and y (one thread per pixel of a tile).
const WORKGROUP: (u32, u32) = (8, 8);

/// Threads a dispatch aims at: with fewer pixels than this in a tile, each pixel gets several
/// threads (slices), each taking every slices-th of its samples into its own slice of the
/// film's sums. Measured on an H200 (docs/benchmarks.md, 2026-11-28, median-split tree): at 512×288, 4 slices
/// (590 k threads) against 1 gave ibpt 1.15× (sibenik, veach-door) to 1.30× (veach-ajar)
/// and pt 1.10-1.51×; at 160×90, 8 slices gave 3.1× (ibpt) and 3.6× (pt).
const THREADS_PER_DISPATCH: u32 = 1 << 19;
/// Film slices at most (each costs 32 bytes per pixel).
const MAX_SLICES: u32 = 16;
/// Whether instant BPT runs its camera and light passes in one kernel. Measured off: without
/// the barrier between the passes but with the registers of both, it was 0.73-0.82× the two
/// kernels at 512×288 (4 slices, SAH tree) on an H200 (0.93-0.96× with median splits).
const FUSED: bool = false;
/// The BVH traversal: stackless, the one measured on an H200 so far (docs/benchmarks.md);
/// the ordered traversal fetches 2.0-2.4× fewer nodes per ray (counted on the CPU) and waits
/// for a device to be timed against it.
const TRAVERSAL: Traversal = Traversal::Stackless;
/// Whether the camera pass runs as a wavefront (wavefront.wgsl), and the light pass too: off,
/// the megakernels being what was measured; the wavefront waits for a device to be timed
/// against them (on lavapipe it made pt 2.3-2.8x faster and ibpt's light pass slower).
const WAVEFRONT: (bool, bool) = (false, false);

/// The megakernels' launch shape. The defaults are the constants above; `bench/gpu_device.sh`
/// sweeps them on a data-centre GPU through the environment (`SKELIGHT_GPU_TILE`,
/// `SKELIGHT_GPU_SAMPLES_PER_DISPATCH`, `SKELIGHT_GPU_WORKGROUP` as `8x8`,
/// `SKELIGHT_GPU_SLICES`, `SKELIGHT_GPU_FUSED` as 0 or 1, `SKELIGHT_GPU_TRAVERSAL` as
/// `stackless`, `ordered` or `hybrid`, `SKELIGHT_GPU_WAVEFRONT` as 0, 1 for the camera pass or 2 for both), so the shape is chosen by
/// measurement rather than by guess. The image does not depend on it: every (pixel, sample)
/// draws the same random numbers whatever thread or dispatch takes it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LaunchShape {
    pub tile: u32,
    pub samples_per_dispatch: u32,
    pub workgroup: (u32, u32),
    /// Threads per pixel in a dispatch (its z extent): more threads in flight for small
    /// images, at the cost of a film slice each.
    pub slices: u32,
    /// Instant BPT's camera and light passes in one kernel, without the barrier between them.
    pub fused: bool,
    /// How the kernels traverse the BVH (and so which of its layouts the device holds).
    pub traversal: Traversal,
    /// The camera pass as a wavefront of kernels over queues of live paths (wavefront.wgsl)
    /// instead of one megakernel.
    pub wavefront: bool,
    /// With `wavefront`, instant BPT's light pass as a wavefront too.
    pub wavefront_light: bool,
}

impl LaunchShape {
    /// The defaults for an adapter of `device_type` and an image of `pixels`, overridden by
    /// the environment.
    pub(crate) fn from_env(device_type: wgpu::DeviceType, pixels: u32) -> Result<LaunchShape, GpuError> {
        let var = |name: &str| std::env::var(name).ok().filter(|v| !v.is_empty());
        let number = |name: &str, default: u32, max: u32| -> Result<u32, GpuError> {
            match var(name) {
                None => Ok(default),
                Some(v) => match v.parse::<u32>() {
                    Ok(n) if (1..=max).contains(&n) => Ok(n),
                    _ => Err(GpuError::Invalid(format!("{name}={v}: expected a whole number from 1 to {max}"))),
                },
            }
        };
        let workgroup = match var("SKELIGHT_GPU_WORKGROUP") {
            None => WORKGROUP,
            Some(v) => {
                let parsed =
                    v.split_once('x').and_then(|(x, y)| Some((x.parse::<u32>().ok()?, y.parse::<u32>().ok()?)));
                match parsed {
                    // On lavapipe, workgroups narrower than its 8 lanes gave a different image
                    // (4x4 and 2x8: veach-door 2.6x too bright, 1.5 rays per sample instead
                    // of 7), not diagnosed: the kernels use no workgroup memory, barrier or
                    // subgroup operation, so a lavapipe fault is likely but unproven. X
                    // starts at 8 until it is understood.
                    Some((x, y)) if x >= 8 && y >= 1 && x.checked_mul(y).is_some_and(|n| n <= 256) => (x, y),
                    _ => {
                        return Err(GpuError::Invalid(format!(
                            "SKELIGHT_GPU_WORKGROUP={v}: expected XxY with X at least 8 and X·Y at most 256, e.g. 8x8"
                        )))
                    }
                }
            }
        };
        let cpu = device_type == wgpu::DeviceType::Cpu;
        let tile = number("SKELIGHT_GPU_TILE", TILE, 4096)?;
        let samples_per_dispatch = number(
            "SKELIGHT_GPU_SAMPLES_PER_DISPATCH",
            if cpu { SAMPLES_PER_DISPATCH_CPU } else { SAMPLES_PER_DISPATCH },
            READBACK_BATCH,
        )?;
        let tile_pixels = pixels.min(tile * tile).max(1);
        let slices = THREADS_PER_DISPATCH.div_ceil(tile_pixels).clamp(1, MAX_SLICES.min(samples_per_dispatch));
        let fused = match var("SKELIGHT_GPU_FUSED").as_deref() {
            None => FUSED,
            Some("0") => false,
            Some("1") => true,
            Some(v) => return Err(GpuError::Invalid(format!("SKELIGHT_GPU_FUSED={v}: expected 0 or 1"))),
        };
        let traversal = match var("SKELIGHT_GPU_TRAVERSAL") {
            None => TRAVERSAL,
            Some(v) => Traversal::from_name(&v).ok_or_else(|| {
                GpuError::Invalid(format!("SKELIGHT_GPU_TRAVERSAL={v}: expected stackless, ordered or hybrid"))
            })?,
        };
        let (wavefront, wavefront_light) = match var("SKELIGHT_GPU_WAVEFRONT").as_deref() {
            None => WAVEFRONT,
            Some("0") => (false, false),
            Some("1") => (true, false),
            Some("2") => (true, true),
            Some(v) => {
                return Err(GpuError::Invalid(format!(
                    "SKELIGHT_GPU_WAVEFRONT={v}: expected 0, 1 (the camera pass) or 2 (both passes)"
                )))
            }
        };
        Ok(LaunchShape {
            tile,
            samples_per_dispatch,
            workgroup,
            slices: number("SKELIGHT_GPU_SLICES", slices, MAX_SLICES)?,
            fused,
            traversal,
            wavefront,
            wavefront_light,
        })
    }

    /// Fewer slices where the film's sums would outgrow a storage buffer of `max_bytes`
    /// (the adapter's limit), or the wavefront's paths (`tile_pixels` a slice) their buffer or
    /// the indirect dispatches' reach: an image the device could render with one slice still
    /// renders.
    pub(crate) fn fit(&mut self, pixels: u64, tile_pixels: u64, max_bytes: u64) -> Result<(), GpuError> {
        let per_slice = pixels * 16;
        if per_slice > max_bytes {
            return Err(GpuError::Device(format!(
                "{pixels} pixels need {per_slice} bytes of sums; the adapter's storage buffers hold {max_bytes}"
            )));
        }
        let mut most = (max_bytes / per_slice).min(MAX_SLICES as u64);
        if self.wavefront {
            let paths = tile_pixels.max(1);
            most =
                most.min(max_bytes / (paths * crate::wavefront::PATH_BYTES)).min(crate::wavefront::MAX_PATHS / paths);
            if most == 0 {
                return Err(GpuError::Invalid(format!(
                    "a wavefront of {paths} paths (a tile of {} pixels a side) does not fit the adapter \
                     ({max_bytes} bytes a buffer, {} paths a wave): set a smaller SKELIGHT_GPU_TILE",
                    self.tile,
                    crate::wavefront::MAX_PATHS
                )));
            }
        }
        self.slices = self.slices.min(most as u32).max(1);
        Ok(())
    }

    /// Refuses a shape the kernels cannot take (one set in code rather than the environment).
    pub(crate) fn check(&self) -> Result<(), GpuError> {
        let (x, y) = self.workgroup;
        let ok = (1..=4096).contains(&self.tile)
            && (1..=READBACK_BATCH).contains(&self.samples_per_dispatch)
            && (1..=MAX_SLICES).contains(&self.slices)
            && x >= 8
            && y >= 1
            && x.checked_mul(y).is_some_and(|n| n <= 256)
            // A tile is a whole number of workgroups, or a tile's last threads would take
            // pixels of the next tile, which would then be rendered twice.
            && self.tile.is_multiple_of(x)
            && self.tile.is_multiple_of(y);
        if ok {
            Ok(())
        } else {
            Err(GpuError::Invalid(format!(
                "launch shape {self:?}: tile 1-4096, samples per dispatch 1-{READBACK_BATCH}, slices 1-{MAX_SLICES}, \
                 workgroup X at least 8, X·Y at most 256, the tile a multiple of X and Y"
            )))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Slices shrink to what the adapter's storage buffers hold (never below one), and an
    /// image whose single slice does not fit is refused with an error, not a panic.
    #[test]
    fn slices_fit_the_adapters_buffers() {
        let mut shape = LaunchShape {
            tile: 512,
            samples_per_dispatch: 16,
            workgroup: (8, 8),
            slices: 16,
            fused: false,
            traversal: Traversal::Stackless,
            wavefront: false,
            wavefront_light: false,
        };
        shape.fit(1000, 1000, 16 * 1000 * 3).unwrap();
        assert_eq!(shape.slices, 3);
        shape.fit(1000, 1000, 1 << 40).unwrap();
        assert_eq!(shape.slices, 3, "fitting never adds slices");
        assert!(matches!(shape.fit(1000, 1000, 100), Err(GpuError::Device(_))));
        // The wavefront's paths: within the indirect dispatches' reach and the buffers.
        let mut wavefront = LaunchShape { slices: 16, wavefront: true, tile: 2048, ..shape };
        wavefront.fit(1 << 22, 1 << 20, 1 << 40).unwrap();
        assert_eq!(wavefront.slices, 3, "4 194 240 paths at most");
        wavefront.fit(1 << 22, 1 << 20, 1 << 28).unwrap();
        assert_eq!(wavefront.slices, 2, "256 MiB buffers hold two slices of 112-byte paths");
        assert!(matches!(wavefront.fit(1 << 22, 1 << 22, 1 << 40), Err(GpuError::Invalid(_))), "a 2048² tile");
        assert!(
            LaunchShape { workgroup: (65536, 65536), ..shape }.check().is_err(),
            "an overflowing workgroup is refused"
        );
    }
}
