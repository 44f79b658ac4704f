//! skelight on the GPU: wgpu compute kernels over the scene flattened into storage buffers
//! ([`flatten`]), traversing their own BVH (data-centre GPUs have no ray-tracing cores, nor
//! does lavapipe, on which the tests run).
//!
//! Today: path tracing (`pt`, the same estimator as the CPU's) over the feature subset
//! [`flatten::FEATURES`]; a scene outside it is refused. Random numbers are drawn per
//! (seed, pixel, sample index), so GPU renders agree with the CPU's in expectation and merge
//! with them sample-count-weighted. Not yet: instant BPT's light-tracing pass, the other
//! BSDFs, lights and the thin lens (issue 35).

pub mod flatten;

use skelight::film::Film;
use skelight::scene::Scene;
use wgpu::util::DeviceExt;

use flatten::{Flat, Params};

#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error("no usable GPU adapter (Vulkan): {0}; install mesa-vulkan-drivers for lavapipe")]
    NoAdapter(String),
    #[error("the GPU device could not be opened: {0}")]
    Device(String),
    #[error("the scene is outside what the GPU renders: {0}")]
    Unsupported(String),
    #[error("{0}")]
    Invalid(String),
    #[error("reading the GPU's results failed: {0}")]
    Readback(String),
}

/// Samples per pixel a dispatch takes at most: long enough to amortise a dispatch, short
/// enough for drivers' watchdogs, and few enough for f32 sums (the film adds them in f64).
const SAMPLES_PER_DISPATCH: u32 = 16;
/// Pixels along a tile's side: any resolution fits any device's dispatch limits.
const TILE: u32 = 512;

/// A GPU path tracer bound to one scene.
pub struct GpuPt {
    device: wgpu::Device,
    queue: wgpu::Queue,
    pipeline: wgpu::ComputePipeline,
    bind_group: wgpu::BindGroup,
    params: Params,
    params_buffer: wgpu::Buffer,
    sums: wgpu::Buffer,
    squares: wgpu::Buffer,
    readback: wgpu::Buffer,
    pixels: usize,
    /// The adapter, in words (name, driver, type).
    pub adapter: String,
}

fn storage(device: &wgpu::Device, label: &str, bytes: &[u8]) -> wgpu::Buffer {
    // Storage buffers may not be empty.
    let contents: &[u8] = if bytes.is_empty() { &[0u8; 16] } else { bytes };
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents,
        usage: wgpu::BufferUsages::STORAGE,
    })
}

impl GpuPt {
    /// Flattens `scene` (refusing what the GPU cannot render) and opens the first Vulkan
    /// adapter: a real GPU when there is one, else lavapipe.
    pub fn new(scene: &Scene) -> Result<GpuPt, GpuError> {
        let flat = flatten::flatten(scene)?;
        pollster::block_on(GpuPt::open(flat))
    }

    async fn open(flat: Flat) -> Result<GpuPt, GpuError> {
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
        desc.backends = wgpu::Backends::VULKAN;
        let instance = wgpu::Instance::new(desc);
        let adapter = instance
            .request_adapter(&wgpu::RequestAdapterOptions {
                power_preference: wgpu::PowerPreference::HighPerformance,
                ..Default::default()
            })
            .await
            .map_err(|e| GpuError::NoAdapter(e.to_string()))?;
        let info = adapter.get_info();
        let name = format!("{} ({}, {:?})", info.name, info.driver, info.device_type);
        let limits = adapter.limits();
        let (device, queue) = adapter
            .request_device(&wgpu::DeviceDescriptor {
                label: Some("skelight"),
                required_limits: wgpu::Limits {
                    max_storage_buffer_binding_size: limits.max_storage_buffer_binding_size,
                    max_buffer_size: limits.max_buffer_size,
                    ..wgpu::Limits::default()
                },
                ..Default::default()
            })
            .await
            .map_err(|e| GpuError::Device(e.to_string()))?;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("pt.wgsl"),
            source: wgpu::ShaderSource::Wgsl(include_str!("pt.wgsl").into()),
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("pt"),
            layout: None,
            module: &module,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
        let pixels = (flat.params.width * flat.params.height) as usize;
        let params_buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("params"),
            size: std::mem::size_of::<Params>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let accumulator = |label| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: (pixels * 16) as u64,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let sums = accumulator("sums");
        let squares = accumulator("squares");
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: (pixels * 32) as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let nodes = storage(&device, "nodes", bytemuck::cast_slice(&flat.nodes));
        let tris = storage(&device, "tris", bytemuck::cast_slice(&flat.tris));
        let materials = storage(&device, "materials", bytemuck::cast_slice(&flat.materials));
        let emitters = storage(&device, "emitters", bytemuck::cast_slice(&flat.emitters));
        let normals = storage(&device, "normals", bytemuck::cast_slice(&flat.normals));
        let layout = pipeline.get_bind_group_layout(0);
        let entries: Vec<wgpu::BindGroupEntry> =
            [&params_buffer, &nodes, &tris, &materials, &emitters, &sums, &squares, &normals]
                .iter()
                .enumerate()
                .map(|(i, b)| wgpu::BindGroupEntry { binding: i as u32, resource: b.as_entire_binding() })
                .collect();
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("pt"),
            layout: &layout,
            entries: &entries,
        });
        Ok(GpuPt {
            device,
            queue,
            pipeline,
            bind_group,
            params: flat.params,
            params_buffer,
            sums,
            squares,
            readback,
            pixels,
            adapter: name,
        })
    }

    /// Renders sample indices `first..first + spp` of every pixel with `seed` into `film`
    /// (box filter, the scene's size), `on_batch` seeing the samples done so far.
    pub fn render_into(
        &mut self,
        film: &mut Film,
        seed: u64,
        first: u32,
        spp: u32,
        mut on_batch: impl FnMut(u32),
    ) -> Result<(), GpuError> {
        let (w, h) = (self.params.width, self.params.height);
        if (film.width, film.height) != (w as usize, h as usize) {
            return Err(GpuError::Invalid(format!("the film is {}×{}, the scene {w}×{h}", film.width, film.height)));
        }
        self.params.seed_lo = seed as u32;
        self.params.seed_hi = (seed >> 32) as u32;
        let mut done = 0;
        while done < spp {
            let n = SAMPLES_PER_DISPATCH.min(spp - done);
            let mut encoder = self.device.create_command_encoder(&Default::default());
            encoder.clear_buffer(&self.sums, 0, None);
            encoder.clear_buffer(&self.squares, 0, None);
            self.queue.submit([encoder.finish()]);
            for y0 in (0..h).step_by(TILE as usize) {
                for x0 in (0..w).step_by(TILE as usize) {
                    let p = Params { first_sample: first + done, samples: n, x0, y0, ..self.params };
                    self.queue.write_buffer(&self.params_buffer, 0, bytemuck::bytes_of(&p));
                    let mut encoder = self.device.create_command_encoder(&Default::default());
                    {
                        let mut pass = encoder.begin_compute_pass(&Default::default());
                        pass.set_pipeline(&self.pipeline);
                        pass.set_bind_group(0, &self.bind_group, &[]);
                        let (tw, th) = (TILE.min(w - x0), TILE.min(h - y0));
                        pass.dispatch_workgroups(tw.div_ceil(8), th.div_ceil(8), 1);
                    }
                    self.queue.submit([encoder.finish()]);
                }
            }
            self.read_into(film)?;
            done += n;
            on_batch(done);
        }
        Ok(())
    }

    /// Adds the accumulators to `film` in f64.
    fn read_into(&self, film: &mut Film) -> Result<(), GpuError> {
        let bytes = (self.pixels * 16) as u64;
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&self.sums, 0, &self.readback, 0, bytes);
        encoder.copy_buffer_to_buffer(&self.squares, 0, &self.readback, bytes, bytes);
        self.queue.submit([encoder.finish()]);
        let slice = self.readback.slice(..);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        self.device
            .poll(wgpu::PollType::Wait { submission_index: None, timeout: None })
            .map_err(|e| GpuError::Readback(e.to_string()))?;
        rx.recv().map_err(|e| GpuError::Readback(e.to_string()))?.map_err(|e| GpuError::Readback(e.to_string()))?;
        {
            let data = slice.get_mapped_range().map_err(|e| GpuError::Readback(e.to_string()))?;
            let values: &[f32] = bytemuck::cast_slice(&data);
            let (sums, squares) = values.split_at(self.pixels * 4);
            for i in 0..self.pixels {
                let s = &sums[i * 4..i * 4 + 4];
                let q = &squares[i * 4..i * 4 + 4];
                let f = |a: &[f32]| [a[0] as f64, a[1] as f64, a[2] as f64];
                film.add_box_samples(i, f(s), f(q), s[3] as f64);
                film.rejected += q[3] as u64;
            }
        }
        self.readback.unmap();
        Ok(())
    }
}
