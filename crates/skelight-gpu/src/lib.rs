//! skelight on the GPU: wgpu compute kernels over the scene flattened into storage buffers
//! ([`flatten`]), traversing their own BVH (data-centre GPUs have no ray-tracing cores, nor
//! does lavapipe, on which the tests run).
//!
//! Estimators ([`Estimator`]): path tracing (`pt`, the CPU's estimator) and instant BPT
//! (`ibpt`, seed 002: a camera pass and a light pass whose splats land on the film with
//! atomic adds, MIS with one float per path), over the feature subset [`flatten::FEATURES`];
//! a scene outside it is refused. Random numbers are drawn per (seed, pixel, sample index),
//! so GPU renders agree with the CPU's in expectation and merge with them. Not yet: the
//! other BSDFs and lights (issue 35).

pub mod bvh;
pub mod flatten;
pub mod job;
mod launch;
mod tables;
mod wavefront;

use skelight::film::Film;
use skelight::scene::Scene;
use wgpu::util::DeviceExt;

pub use bvh::Traversal;
use flatten::{Flat, Params};
pub use launch::LaunchShape;
use launch::READBACK_BATCH;

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

/// Storage buffers the kernels bind (scene: 5; film: sums, squares, splats; ray counters).
const STORAGE_BUFFERS: u32 = 10;

/// What the GPU renders with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Estimator {
    /// Path tracing with next-event estimation (the CPU's `pt`).
    Pt,
    /// Instant BPT (the CPU's `ibpt`): path tracing and light tracing, one light path per
    /// camera sample, weighted by the power heuristic.
    Ibpt,
    /// Light tracing alone (the CPU's `lt`): the light pass unweighted, one light path per
    /// pixel sample. Sees no specular surface; it checks the light pass apart from the MIS.
    Lt,
}

impl Estimator {
    /// Every GPU estimator, each under its CPU twin's registry name.
    pub const ALL: [Estimator; 3] = [Estimator::Pt, Estimator::Ibpt, Estimator::Lt];

    /// The estimator of registry name `name` (its canonical name), if the GPU has it.
    pub fn from_name(name: &str) -> Option<Estimator> {
        Estimator::ALL.into_iter().find(|e| e.name() == name)
    }

    /// Its registry name.
    pub fn name(self) -> &'static str {
        match self {
            Estimator::Pt => "pt",
            Estimator::Ibpt => "ibpt",
            Estimator::Lt => "lt",
        }
    }

    /// The registry parameters its kernels honour; any other the registry declares for it
    /// must keep its default on the GPU (skelight_gpu::job::kernels_for refuses it). pt, ibpt
    /// and lt declare none today; an estimator that does (`vpl`) lists here those its
    /// kernels read.
    pub fn honours(self) -> &'static [&'static str] {
        &[]
    }
}

/// What a renderer keeps on the device. A path's state lives in the registers of its thread
/// (instant BPT stores no vertices: seed 002 §3.3), so no device memory grows with the paths
/// in flight; the film's accumulators grow with the pixels.
#[derive(Clone, Copy, Debug)]
pub struct Memory {
    /// Triangles, BVH nodes, shading normals, materials and emitters.
    pub scene_bytes: u64,
    /// Sums, squares and splats per pixel.
    pub film_bytes_per_pixel: u64,
    /// Device memory per path in flight (at most: a traversal's stack may stay in registers).
    pub path_state_bytes: u64,
}

/// Which passes a render of `estimator` under a launch shape runs, and so which megakernels
/// it compiles: lavapipe takes seconds to compile each, and a path tracer has no light pass,
/// the fused instant-BPT kernel none apart from the camera's, the wavefront its own kernels.
struct Kernels {
    /// Light sub-paths are traced (lt, ibpt unfused).
    light_pass: bool,
    /// The camera megakernel runs (no wavefront).
    camera: bool,
    /// The light megakernel runs (a light pass, not as a wavefront).
    light: bool,
}

impl Kernels {
    fn of(estimator: Estimator, shape: &LaunchShape) -> Kernels {
        let fused = shape.fused && !shape.wavefront && estimator == Estimator::Ibpt;
        let light_pass = estimator != Estimator::Pt && !fused;
        let light = light_pass && !(shape.wavefront && shape.wavefront_light);
        Kernels { light_pass, camera: !shape.wavefront, light }
    }
}

/// A GPU renderer bound to one scene and estimator.
pub struct GpuRenderer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    /// The kernels' module, the BVH's nodes and the triangles (for [`GpuRenderer::trace`]).
    module: wgpu::ShaderModule,
    nodes: wgpu::Buffer,
    tris: wgpu::Buffer,
    /// The megakernels, compiled only where a render dispatches them (see [`Kernels`]).
    camera_pass: Option<wgpu::ComputePipeline>,
    light_pass: Option<wgpu::ComputePipeline>,
    estimator: Estimator,
    bind_group: wgpu::BindGroup,
    params: Params,
    params_buffer: wgpu::Buffer,
    sums: wgpu::Buffer,
    squares: wgpu::Buffer,
    splats: wgpu::Buffer,
    counters: wgpu::Buffer,
    readback: wgpu::Buffer,
    pixels: usize,
    /// Floats per pixel in `splats`: 3, or 10 under the tent filter.
    splat_floats: usize,
    shape: LaunchShape,
    /// Where the ordered layout's nodes begin in `nodes` (the kernels' PAIR_ROOT).
    pair_root: u32,
    /// The wavefront camera pass's buffers and kernels, when the shape asks for it.
    wavefront: Option<wavefront::Wavefront>,
    rays: u64,
    memory: Memory,
    /// The adapter, in words (name, driver, type).
    pub adapter: String,
    /// How splats are added: by the adapter's float atomics or by compare and swap.
    pub splat_mode: Splats,
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

/// Waits until the device has done all that was submitted.
fn wait(device: &wgpu::Device) -> Result<(), GpuError> {
    device
        .poll(wgpu::PollType::Wait { submission_index: None, timeout: None })
        .map(|_| ())
        .map_err(|e| GpuError::Readback(e.to_string()))
}

/// How the light pass's splats (and the tent filter's camera samples) are added to the film.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Splats {
    /// Float atomics where the adapter has them (VK_EXT_shader_atomic_float), else compare
    /// and swap.
    Auto,
    /// A float's bits swapped in by compare and swap: what adapters without float atomics
    /// get, and chosen on purpose to test that path on one that has them.
    CompareAndSwap,
    /// The adapter's float atomics (reported by [`GpuRenderer::splat_mode`]; not a request).
    FloatAtomics,
}

/// What the adapter offers the kernels, and the launch shape they run with.
struct Plan {
    /// The adapter, in words (name, driver, type).
    name: String,
    limits: wgpu::Limits,
    float_atomics: bool,
    shape: LaunchShape,
    storage_buffers: u32,
}

/// The kernels' plan on `adapter` for a `width`×`height` film: the launch shape from the
/// defaults, the environment and `adjust`, fitted to the adapter's buffers. Every refusal
/// that needs the adapter but not the device (a bad SKELIGHT_GPU_* variable, too few
/// storage buffers, a film too large) is here, so that GpuRenderer::check makes them too.
fn plan(
    adapter: &wgpu::Adapter,
    width: u32,
    height: u32,
    splats: Splats,
    adjust: impl FnOnce(&mut LaunchShape),
) -> Result<Plan, GpuError> {
    let info = adapter.get_info();
    let name = format!("{} ({}, {:?})", info.name, info.driver, info.device_type);
    let limits = adapter.limits();
    let float_atomics =
        splats != Splats::CompareAndSwap && adapter.features().contains(wgpu::Features::SHADER_FLOAT32_ATOMIC);
    let mut shape = LaunchShape::from_env(info.device_type, width * height)?;
    adjust(&mut shape);
    shape.check()?;
    let storage_buffers = STORAGE_BUFFERS + if shape.wavefront { wavefront::BUFFERS } else { 0 };
    if limits.max_storage_buffers_per_shader_stage < storage_buffers {
        return Err(GpuError::Device(format!(
            "{name} offers {} storage buffers per shader stage; the kernels need {storage_buffers}",
            limits.max_storage_buffers_per_shader_stage
        )));
    }
    let max_bytes = limits.max_storage_buffer_binding_size.min(limits.max_buffer_size);
    let (w, h) = (width as u64, height as u64);
    shape.fit(w * h, w.min(shape.tile as u64) * h.min(shape.tile as u64), max_bytes)?;
    Ok(Plan { name, limits, float_atomics, shape, storage_buffers })
}

/// The Vulkan adapter the kernels run on (the most powerful one).
async fn adapter() -> Result<wgpu::Adapter, GpuError> {
    let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
    desc.backends = wgpu::Backends::VULKAN;
    wgpu::Instance::new(desc)
        .request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            ..Default::default()
        })
        .await
        .map_err(|e| GpuError::NoAdapter(e.to_string()))
}

impl GpuRenderer {
    /// Flattens `scene` (refusing what the GPU cannot render) and opens the first Vulkan
    /// adapter: a real GPU when there is one, else lavapipe.
    pub fn new(scene: &Scene, estimator: Estimator) -> Result<GpuRenderer, GpuError> {
        GpuRenderer::with_splats(scene, estimator, Splats::Auto)
    }

    /// [`GpuRenderer::new`] with the way splats are added chosen ([`Splats::Auto`] or
    /// [`Splats::CompareAndSwap`]).
    pub fn with_splats(scene: &Scene, estimator: Estimator, splats: Splats) -> Result<GpuRenderer, GpuError> {
        GpuRenderer::with_shape(scene, estimator, splats, |_| {})
    }

    /// [`GpuRenderer::with_splats`] with the launch shape changed by `adjust` after the
    /// defaults and the environment have set it (tests and benchmarks: the samples do not
    /// depend on it).
    pub fn with_shape(
        scene: &Scene,
        estimator: Estimator,
        splats: Splats,
        adjust: impl FnOnce(&mut LaunchShape),
    ) -> Result<GpuRenderer, GpuError> {
        let flat = flatten::flatten(scene)?;
        pollster::block_on(GpuRenderer::open(flat, estimator, splats, adjust))
    }

    /// Whether `scene` can be rendered here, without building the renderer: the scene is
    /// inside the feature subset (flatten::supported), Vulkan offers an adapter, and the
    /// launch shape (the environment's included) and the film fit it. `compare` asks before
    /// its first run, so that a `gpu:` estimator it cannot run fails at once.
    pub fn check(scene: &Scene) -> Result<(), GpuError> {
        flatten::supported(scene)?;
        let adapter = pollster::block_on(adapter())?;
        let s = &scene.settings;
        plan(&adapter, s.width as u32, s.height as u32, Splats::Auto, |_| {}).map(|_| ())
    }

    async fn open(
        mut flat: Flat,
        estimator: Estimator,
        splats: Splats,
        adjust: impl FnOnce(&mut LaunchShape),
    ) -> Result<GpuRenderer, GpuError> {
        flat.params.bidirectional = match estimator {
            Estimator::Pt => 0,
            Estimator::Ibpt => 1,
            Estimator::Lt => 2,
        };
        let adapter = adapter().await?;
        let Plan { name, limits, float_atomics, shape, storage_buffers } =
            plan(&adapter, flat.params.width, flat.params.height, splats, adjust)?;
        let (device, queue) = adapter
            .request_device(&wgpu::DeviceDescriptor {
                label: Some("skelight"),
                required_features: if float_atomics {
                    wgpu::Features::SHADER_FLOAT32_ATOMIC
                } else {
                    wgpu::Features::empty()
                },
                required_limits: wgpu::Limits {
                    max_storage_buffer_binding_size: limits.max_storage_buffer_binding_size,
                    max_storage_buffers_per_shader_stage: storage_buffers,
                    max_buffer_size: limits.max_buffer_size,
                    ..wgpu::Limits::default()
                },
                ..Default::default()
            })
            .await
            .map_err(|e| GpuError::Device(e.to_string()))?;
        // Splats add with float atomics where the adapter has them, else by compare and swap.
        let splat = if float_atomics { include_str!("splat_f32.wgsl") } else { include_str!("splat_cas.wgsl") };
        // The BVH layouts the traversal reads, and the `traverse` that calls it.
        let (device_nodes, pair_root) = shape.traversal.device_nodes(&flat.nodes);
        let source = [
            include_str!("common.wgsl"),
            include_str!("traverse_stackless.wgsl"),
            include_str!("traverse_ordered.wgsl"),
            shape.traversal.dispatcher(),
            include_str!("texture.wgsl"),
            include_str!("environment.wgsl"),
            include_str!("light.wgsl"),
            include_str!("bsdf.wgsl"),
            splat,
            include_str!("film.wgsl"),
            include_str!("camera_pass.wgsl"),
            include_str!("light_pass.wgsl"),
        ];
        let wavefront_source = if shape.wavefront { wavefront::source() } else { String::new() };
        let (wx, wy) = shape.workgroup;
        let source = (source.concat() + &wavefront_source)
            .replace("@workgroup_size(8, 8)", &format!("@workgroup_size({wx}, {wy})"));
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("skelight kernels"),
            source: wgpu::ShaderSource::Wgsl(source.into()),
        });
        // One layout for both passes (each uses part of it).
        let binding = |i: u32, ty: wgpu::BufferBindingType| wgpu::BindGroupLayoutEntry {
            binding: i,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer { ty, has_dynamic_offset: false, min_binding_size: None },
            count: None,
        };
        let read = wgpu::BufferBindingType::Storage { read_only: true };
        let write = wgpu::BufferBindingType::Storage { read_only: false };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("scene"),
            entries: &[
                binding(0, wgpu::BufferBindingType::Uniform),
                binding(1, read),
                binding(2, read),
                binding(3, read),
                binding(4, read),
                binding(5, write),
                binding(6, write),
                binding(7, read),
                binding(8, write),
                binding(9, write),
                binding(10, read),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("scene"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline_with = |layout: &wgpu::PipelineLayout, entry: &str, constants: &[(&str, f64)]| {
            let constants = [constants, &[("PAIR_ROOT", pair_root as f64)]].concat();
            let constants = constants.as_slice();
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: Some(layout),
                module: &module,
                entry_point: Some(entry),
                compilation_options: wgpu::PipelineCompilationOptions { constants, ..Default::default() },
                cache: None,
            })
        };
        let pipeline = |entry: &str, constants: &[(&str, f64)]| pipeline_with(&pipeline_layout, entry, constants);
        // The fused instant-BPT kernel is the camera pass with its `FUSED` constant set.
        let fused = shape.fused && estimator == Estimator::Ibpt;
        let kernels = Kernels::of(estimator, &shape);
        let camera_pass = kernels.camera.then(|| pipeline("camera_main", &[("FUSED", if fused { 1.0 } else { 0.0 })]));
        let light_pass = kernels.light.then(|| pipeline("light_main", &[]));
        let wavefront = if shape.wavefront {
            let tile = (shape.tile.min(flat.params.width), shape.tile.min(flat.params.height));
            let light = kernels.light_pass && shape.wavefront_light;
            let pipeline = |l: &wgpu::PipelineLayout, e: &str| pipeline_with(l, e, &[]);
            Some(wavefront::Wavefront::new(&device, &layout, tile, shape.slices, light, &pipeline)?)
        } else {
            None
        };
        let pixels = (flat.params.width * flat.params.height) as usize;
        // Light splats (rgb), and under the tent filter the camera samples' weighted sums (7).
        let splat_floats = if flat.params.filter_radius > 0.0 { 10 } else { 3 };
        let params_buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("params"),
            size: std::mem::size_of::<Params>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let accumulator = |label| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: (pixels * 16 * shape.slices as usize) as u64,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let sums = accumulator("sums");
        let squares = accumulator("squares");
        let splats = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("splats"),
            size: (pixels * 4 * splat_floats) as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let counters = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("counters"),
            size: 8,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: (pixels * (32 * shape.slices as usize + 4 * splat_floats) + 8) as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let scene_bytes = [
            std::mem::size_of_val(device_nodes.as_slice()),
            std::mem::size_of_val(flat.tris.as_slice()),
            std::mem::size_of_val(flat.materials.as_slice()),
            std::mem::size_of_val(flat.emitters.as_slice()),
            std::mem::size_of_val(flat.attributes.as_slice()),
            std::mem::size_of_val(flat.data.as_slice()),
        ]
        .iter()
        .sum::<usize>() as u64;
        let nodes = storage(&device, "nodes", bytemuck::cast_slice(&device_nodes));
        let tris = storage(&device, "tris", bytemuck::cast_slice(&flat.tris));
        let materials = storage(&device, "materials", bytemuck::cast_slice(&flat.materials));
        let emitters = storage(&device, "emitters", bytemuck::cast_slice(&flat.emitters));
        let attributes = storage(&device, "attributes", bytemuck::cast_slice(&flat.attributes));
        let data = storage(&device, "data", bytemuck::cast_slice(&flat.data));
        let entries: Vec<wgpu::BindGroupEntry> = [
            &params_buffer,
            &nodes,
            &tris,
            &materials,
            &emitters,
            &sums,
            &squares,
            &attributes,
            &splats,
            &counters,
            &data,
        ]
        .iter()
        .enumerate()
        .map(|(i, b)| wgpu::BindGroupEntry { binding: i as u32, resource: b.as_entire_binding() })
        .collect();
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("scene"),
            layout: &layout,
            entries: &entries,
        });
        Ok(GpuRenderer {
            device,
            queue,
            module,
            nodes,
            tris,
            camera_pass,
            light_pass,
            estimator,
            bind_group,
            params: flat.params,
            params_buffer,
            sums,
            squares,
            splats,
            counters,
            readback,
            rays: 0,
            memory: Memory {
                scene_bytes,
                film_bytes_per_pixel: 32 * shape.slices as u64 + 4 * splat_floats as u64,
                // The ordered traversal's stack: a node and an entry distance per level, which
                // the shader compiler keeps in registers or spills to local memory.
                path_state_bytes: match shape.traversal {
                    Traversal::Stackless => 0,
                    Traversal::Ordered | Traversal::Hybrid => (bvh::MAX_DEPTH * 8) as u64,
                } + wavefront.as_ref().map_or(0, |w| w.bytes_per_path),
            },
            splat_floats,
            pixels,
            shape,
            pair_root,
            wavefront,
            adapter: name,
            splat_mode: if float_atomics { Splats::FloatAtomics } else { Splats::CompareAndSwap },
        })
    }

    /// Renders sample indices `first..first + spp` of every pixel with `seed` into `film`
    /// (the scene's size and filter), `on_batch` seeing the samples done so far. The samples
    /// are summed on the device in f32 in groups aligned to multiples of READBACK_BATCH from
    /// sample 0, then in f64 into the film: calls that split a range at those multiples give
    /// the film of one call, bit for bit.
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
            // A batch of READBACK_BATCH samples per pixel (up to the next multiple)
            // accumulates on the device (f32), in dispatches of `samples_per_dispatch`, then
            // is added to the film in f64.
            let n = (READBACK_BATCH - (first + done) % READBACK_BATCH).min(spp - done);
            let mut encoder = self.device.create_command_encoder(&Default::default());
            encoder.clear_buffer(&self.sums, 0, None);
            encoder.clear_buffer(&self.squares, 0, None);
            encoder.clear_buffer(&self.splats, 0, None);
            encoder.clear_buffer(&self.counters, 0, None);
            self.queue.submit([encoder.finish()]);
            let LaunchShape { tile, samples_per_dispatch, workgroup: (wx, wy), slices, .. } = self.shape;
            let light_pass = Kernels::of(self.estimator, &self.shape).light_pass;
            for offset in (0..n).step_by(samples_per_dispatch as usize) {
                let samples = samples_per_dispatch.min(n - offset);
                for y0 in (0..h).step_by(tile as usize) {
                    for x0 in (0..w).step_by(tile as usize) {
                        let p = Params { first_sample: first + done + offset, samples, x0, y0, slices, ..self.params };
                        let (tw, th) = (tile.min(w - x0), tile.min(h - y0));
                        // Slices beyond the samples of the dispatch would have nothing to do.
                        let depth = slices.min(samples);
                        let light_wavefront = light_pass && self.shape.wavefront_light;
                        if let Some(wavefront) = &self.wavefront {
                            // The camera pass (and the light pass) in waves of `slices` samples
                            // per pixel.
                            let passes: &[wavefront::Pass] = if light_wavefront {
                                &[wavefront::Pass::Camera, wavefront::Pass::Light]
                            } else {
                                &[wavefront::Pass::Camera]
                            };
                            for &which in passes {
                                for wave in 0..samples.div_ceil(slices) {
                                    let (wf_tile_w, wf_tile_h) = wavefront.tile;
                                    let p = Params { wave, wf_tile_w, wf_tile_h, ..p };
                                    self.queue.write_buffer(&self.params_buffer, 0, bytemuck::bytes_of(&p));
                                    wavefront.run(
                                        which,
                                        (&self.device, &self.queue),
                                        &self.bind_group,
                                        (tw, th, depth),
                                        (wx, wy),
                                        self.params.max_depth,
                                    )?;
                                }
                            }
                            if self.light_pass.is_none() {
                                continue;
                            }
                        }
                        self.queue.write_buffer(&self.params_buffer, 0, bytemuck::bytes_of(&p));
                        let mut encoder = self.device.create_command_encoder(&Default::default());
                        {
                            let mut pass = encoder.begin_compute_pass(&Default::default());
                            pass.set_bind_group(0, &self.bind_group, &[]);
                            for kernel in [&self.camera_pass, &self.light_pass].into_iter().flatten() {
                                pass.set_pipeline(kernel);
                                pass.dispatch_workgroups(tw.div_ceil(wx), th.div_ceil(wy), depth);
                            }
                        }
                        self.queue.submit([encoder.finish()]);
                    }
                }
            }
            self.read_into(film, n)?;
            done += n;
            on_batch(done);
        }
        Ok(())
    }

    /// `bench rays --device gpu`: traces `rays` (origin, t_max, direction, 1 for any hit else
    /// 0) with the BVH traversal alone, no shading, `rounds` times after a warm-up, and gives
    /// the best time and each ray's hit distance (its t_max where it hit nothing; for an
    /// any-hit ray, the hit it stopped at).
    pub fn trace(&self, rays: &[[f32; 8]], rounds: usize) -> Result<(std::time::Duration, Vec<f32>), GpuError> {
        let entry = |i: u32, read_only: bool| wgpu::BindGroupLayoutEntry {
            binding: i,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let layout = self.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("rays"),
            entries: &[entry(1, true), entry(2, true), entry(11, true), entry(12, false)],
        });
        let pipeline = self.device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("rays_main"),
            layout: Some(&self.device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("rays"),
                bind_group_layouts: &[Some(&layout)],
                immediate_size: 0,
            })),
            module: &self.module,
            entry_point: Some("rays_main"),
            compilation_options: wgpu::PipelineCompilationOptions {
                constants: &[("PAIR_ROOT", self.pair_root as f64)],
                ..Default::default()
            },
            cache: None,
        });
        let ray_buffer = storage(&self.device, "bench rays", bytemuck::cast_slice(rays));
        let bytes = (rays.len().max(1) * 4) as u64;
        let hits = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("bench hits"),
            size: bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let readback = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("bench hits readback"),
            size: bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let bind_group = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("rays"),
            layout: &layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 1, resource: self.nodes.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: self.tris.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 11, resource: ray_buffer.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 12, resource: hits.as_entire_binding() },
            ],
        });
        // Workgroups of 64 rays, laid out in two dimensions within the per-dimension limit.
        let groups = (rays.len() as u32).div_ceil(64).max(1);
        let (gx, gy) = (groups.min(65535), groups.div_ceil(65535));
        let mut best = std::time::Duration::MAX;
        for round in 0..=rounds {
            let mut encoder = self.device.create_command_encoder(&Default::default());
            {
                let mut pass = encoder.begin_compute_pass(&Default::default());
                pass.set_pipeline(&pipeline);
                pass.set_bind_group(0, &bind_group, &[]);
                pass.dispatch_workgroups(gx, gy, 1);
            }
            let start = std::time::Instant::now();
            self.queue.submit([encoder.finish()]);
            self.wait()?;
            // Round 0 warms up (the driver's compilation, first touches of the buffers).
            if round > 0 {
                best = best.min(start.elapsed());
            }
        }
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&hits, 0, &readback, 0, bytes);
        self.queue.submit([encoder.finish()]);
        let slice = readback.slice(..);
        slice.map_async(wgpu::MapMode::Read, |_| {});
        self.wait()?;
        let data = slice.get_mapped_range().map_err(|e| GpuError::Readback(e.to_string()))?;
        let distances = bytemuck::cast_slice::<u8, f32>(&data)[..rays.len()].to_vec();
        Ok((best, distances))
    }

    /// How the kernels are launched (tile, samples per dispatch, workgroup, slices).
    pub fn shape(&self) -> LaunchShape {
        self.shape
    }

    /// Rays traced (closest-hit and shadow) since the renderer was made.
    pub fn rays_traced(&self) -> u64 {
        self.rays
    }

    /// What the renderer keeps on the device.
    pub fn memory(&self) -> Memory {
        self.memory
    }

    /// Waits until the device has done everything submitted.
    fn wait(&self) -> Result<(), GpuError> {
        wait(&self.device)
    }

    /// Adds the accumulators of a batch of `spp` samples per pixel to `film` in f64.
    fn read_into(&mut self, film: &mut Film, spp: u32) -> Result<(), GpuError> {
        let bytes = (self.pixels * 16 * self.shape.slices as usize) as u64;
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&self.sums, 0, &self.readback, 0, bytes);
        encoder.copy_buffer_to_buffer(&self.squares, 0, &self.readback, bytes, bytes);
        let splat_bytes = (self.pixels * 4 * self.splat_floats) as u64;
        encoder.copy_buffer_to_buffer(&self.splats, 0, &self.readback, 2 * bytes, splat_bytes);
        encoder.copy_buffer_to_buffer(&self.counters, 0, &self.readback, 2 * bytes + splat_bytes, 8);
        self.queue.submit([encoder.finish()]);
        let slice = self.readback.slice(..);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        self.wait()?;
        rx.recv().map_err(|e| GpuError::Readback(e.to_string()))?.map_err(|e| GpuError::Readback(e.to_string()))?;
        {
            let data = slice.get_mapped_range().map_err(|e| GpuError::Readback(e.to_string()))?;
            let values: &[f32] = bytemuck::cast_slice(&data);
            let slice_floats = self.pixels * 4;
            let (sums, rest) = values.split_at(slice_floats * self.shape.slices as usize);
            let (squares, rest) = rest.split_at(slice_floats * self.shape.slices as usize);
            let (splats, rest) = rest.split_at(self.pixels * 3);
            let (filtered, counters) = rest.split_at(self.pixels * (self.splat_floats - 3));
            let (lo, hi) = (counters[0].to_bits() as u64, counters[1].to_bits() as u64);
            self.rays += lo | hi << 32;
            let f = |a: &[f32]| [a[0] as f64, a[1] as f64, a[2] as f64];
            for i in 0..self.pixels {
                for z in 0..self.shape.slices as usize {
                    let k = z * slice_floats + i * 4;
                    let (s, q) = (&sums[k..k + 4], &squares[k..k + 4]);
                    if filtered.is_empty() {
                        film.add_pixel_samples(i, f(s), f(q), s[3] as f64);
                    }
                    film.rejected += q[3] as u64;
                }
                if !filtered.is_empty() {
                    let t = &filtered[i * 7..i * 7 + 7];
                    film.add_pixel_samples(i, f(t), f(&t[3..]), t[6] as f64);
                }
            }
            if self.estimator != Estimator::Pt {
                for i in 0..self.pixels {
                    film.add_pixel_splats(i, f(&splats[i * 3..i * 3 + 3]));
                }
                // One light path per camera sample.
                film.splat_paths += self.pixels as u64 * spp as u64;
            }
        }
        self.readback.unmap();
        Ok(())
    }
}
