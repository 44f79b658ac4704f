//! The wavefront camera pass (wavefront.wgsl): its buffers, pipelines and the sequence of
//! dispatches of one wave. Chosen by `SKELIGHT_GPU_WAVEFRONT=1` (launch.rs) against the
//! megakernel, for measurement on a data-centre GPU (docs/benchmarks.md).

use crate::GpuError;

/// The kernels' source: wavefront.wgsl, and wave_walk.wgsl once per pass.
pub(crate) fn source() -> String {
    let walk = include_str!("wave_walk.wgsl");
    let pass = |prefix: &str, paths: &str, hit: &str, walk_fn: &str, rays: &str, stream: &str, path_type: &str| {
        walk.replace("{prefix}", prefix)
            .replace("{path_type}", path_type)
            .replace("{paths}", paths)
            .replace("{hit}", hit)
            .replace("{walk}", walk_fn)
            .replace("{rays}", rays)
            .replace("{stream}", stream)
    };
    [
        include_str!("wavefront.wgsl").to_string(),
        pass("wf", "wf_paths", "camera_hit", "camera_walk", "wf_shadows", "0u", "CameraPath"),
        pass("lw", "wf_light_paths", "light_hit", "light_walk", "wf_lens_rays", "1u", "LightPath"),
    ]
    .concat()
}

/// Bytes of one path's state (`CameraPath`, `LightPath`), hit (`Hit`), shadow ray
/// (`ShadowRay`) and segment to the lens (`LensRay`).
pub(crate) const PATH_BYTES: u64 = 112;
const HIT_BYTES: u64 = 16;
const SHADOW_BYTES: u64 = 48;
const LENS_RAY_BYTES: u64 = 64;
/// Storage buffers of the wavefront's bind groups (group 1, and group 2: the arguments).
pub(crate) const BUFFERS: u32 = 9;
/// Paths a wave may hold: the indirect dispatches' workgroups (64 threads each) stay within
/// the 65 535 a dimension may have.
pub(crate) const MAX_PATHS: u64 = 65_535 * 64;
/// Bounces encoded between two checks of how many paths are alive, when there may be more
/// than twice as many (unbounded or deep).
const BOUNCES_PER_CHECK: u32 = 8;
/// At a check, walks finish in one thread each (the tail kernels) once fewer than this share
/// of the wave is alive: a light path in a closed room (veach-door, unbounded depth) lives
/// tens of bounces, and on lavapipe each bounce's round of dispatches cost 40 ms whatever
/// the paths left (the light wavefront 8× slower than its megakernel without the tail).
const TAIL_SHARE: u32 = 16;
/// The megakernel's bound on a walk's vertices (camera_pass.wgsl).
const MAX_BOUNCES: u32 = 4097;

/// One pass's kernels: the first rays, closest hits, shading, the rays it makes (shadow rays,
/// or segments to the lens) and, for the camera, the radiance into the film.
struct Kernels {
    start: wgpu::ComputePipeline,
    extend: wgpu::ComputePipeline,
    shade: wgpu::ComputePipeline,
    trace: wgpu::ComputePipeline,
    /// The walks left, each finished in one thread.
    tail: wgpu::ComputePipeline,
    finish: Option<wgpu::ComputePipeline>,
}

/// Which of instant BPT's passes a wave runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Pass {
    Camera,
    Light,
}

pub(crate) struct Wavefront {
    camera: Kernels,
    light: Kernels,
    args: wgpu::ComputePipeline,
    /// Queue A in and B out, and the other way round.
    groups: [wgpu::BindGroup; 2],
    args_group: wgpu::BindGroup,
    counts: wgpu::Buffer,
    args_buffer: wgpu::Buffer,
    counts_readback: wgpu::Buffer,
    /// The tile size the path buffers are laid out by.
    pub(crate) tile: (u32, u32),
    /// Device memory per path in flight: the camera's state, a hit, a shadow ray and two queue
    /// entries; with the light pass, its state and a segment to the lens.
    pub(crate) bytes_per_path: u64,
}

impl Wavefront {
    /// Buffers for `tile.0` · `tile.1` · `slices` paths (at most [`MAX_PATHS`], and the
    /// adapter's buffer size: LaunchShape::fit), for the light pass too when `light`, and the
    /// kernels' pipelines over `scene_layout`
    /// (group 0) and the wavefront's group 1; `pipeline` builds one from a layout and entry.
    pub(crate) fn new(
        device: &wgpu::Device,
        scene_layout: &wgpu::BindGroupLayout,
        tile: (u32, u32),
        slices: u32,
        light: bool,
        pipeline: &dyn Fn(&wgpu::PipelineLayout, &str) -> wgpu::ComputePipeline,
    ) -> Result<Wavefront, GpuError> {
        let paths = tile.0 as u64 * tile.1 as u64 * slices as u64;
        if paths > MAX_PATHS {
            return Err(GpuError::Invalid(format!("a wave of {paths} paths: at most {MAX_PATHS}")));
        }
        let buffer = |label: &str, size: u64, usage: wgpu::BufferUsages| {
            device.create_buffer(&wgpu::BufferDescriptor { label: Some(label), size, usage, mapped_at_creation: false })
        };
        let storage = wgpu::BufferUsages::STORAGE;
        let state = buffer("wavefront paths", paths * PATH_BYTES, storage);
        let hits = buffer("wavefront hits", paths * HIT_BYTES, storage);
        let shadows = buffer("wavefront shadow rays", paths * SHADOW_BYTES, storage);
        let queues = [buffer("wavefront queue a", paths * 4, storage), buffer("wavefront queue b", paths * 4, storage)];
        // The light pass's walks and lens segments, only where it runs as a wavefront (else a
        // token buffer, for the bind group).
        let light_paths = if light { paths } else { 1 };
        let light_state = buffer("wavefront light paths", light_paths * PATH_BYTES, storage);
        let lens_rays = buffer("wavefront lens rays", light_paths * LENS_RAY_BYTES, storage);
        let counts =
            buffer("wavefront counts", 16, storage | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST);
        let args_buffer = buffer("wavefront dispatch arguments", 24, storage | wgpu::BufferUsages::INDIRECT);
        let counts_readback =
            buffer("wavefront counts readback", 16, wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST);
        let entry = |i: u32| wgpu::BindGroupLayoutEntry {
            binding: i,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only: false },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("wavefront"),
            entries: &(0..BUFFERS - 1).map(entry).collect::<Vec<_>>(),
        });
        let args_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("wavefront arguments"),
            entries: &[entry(0)],
        });
        let args_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("wavefront arguments"),
            layout: &args_layout,
            entries: &[wgpu::BindGroupEntry { binding: 0, resource: args_buffer.as_entire_binding() }],
        });
        let group = |a: usize, b: usize| {
            let resources = [&state, &hits, &shadows, &queues[a], &queues[b], &counts, &light_state, &lens_rays];
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("wavefront"),
                layout: &layout,
                entries: &resources
                    .iter()
                    .enumerate()
                    .map(|(i, r)| wgpu::BindGroupEntry { binding: i as u32, resource: r.as_entire_binding() })
                    .collect::<Vec<_>>(),
            })
        };
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("wavefront"),
            bind_group_layouts: &[Some(scene_layout), Some(&layout)],
            immediate_size: 0,
        });
        let args_pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("wavefront arguments"),
            bind_group_layouts: &[Some(scene_layout), Some(&layout), Some(&args_layout)],
            immediate_size: 0,
        });
        let kernel = |entry: &str| pipeline(&pipeline_layout, entry);
        Ok(Wavefront {
            camera: Kernels {
                start: kernel("wf_start"),
                extend: kernel("wf_extend"),
                shade: kernel("wf_shade"),
                trace: kernel("wf_shadow"),
                tail: kernel("wf_tail"),
                finish: Some(kernel("wf_finish")),
            },
            light: Kernels {
                start: kernel("lw_start"),
                extend: kernel("lw_extend"),
                shade: kernel("lw_shade"),
                trace: kernel("lw_connect"),
                tail: kernel("lw_tail"),
                finish: None,
            },
            args: pipeline(&args_pipeline_layout, "wf_args_main"),
            args_group,
            groups: [group(0, 1), group(1, 0)],
            counts,
            args_buffer,
            counts_readback,
            tile,
            bytes_per_path: PATH_BYTES
                + HIT_BYTES
                + SHADOW_BYTES
                + 8
                + if light { PATH_BYTES + LENS_RAY_BYTES } else { 0 },
        })
    }

    /// Runs one wave of a pass (Params already written: the tile, its samples, `wave`): the
    /// first rays of its paths, `max_depth` bounces (or until none is alive, checked every few
    /// bounces when there may be many), and for the camera the paths' radiance into the film's
    /// sums (the light pass splats as it goes).
    pub(crate) fn run(
        &self,
        which: Pass,
        (device, queue): (&wgpu::Device, &wgpu::Queue),
        scene: &wgpu::BindGroup,
        (tw, th, depth): (u32, u32, u32),
        (wx, wy): (u32, u32),
        max_depth: i32,
    ) -> Result<(), GpuError> {
        let kernels = match which {
            Pass::Camera => &self.camera,
            Pass::Light => &self.light,
        };
        let mut encoder = device.create_command_encoder(&Default::default());
        encoder.clear_buffer(&self.counts, 0, None);
        let pass = |encoder: &mut wgpu::CommandEncoder, side: usize, run: &dyn Fn(&mut wgpu::ComputePass)| {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_bind_group(0, scene, &[]);
            pass.set_bind_group(1, &self.groups[side], &[]);
            run(&mut pass);
        };
        // The camera rays, appended to queue b (group 0's out). Each wf_args then makes the
        // paths appended the queue in, and the bind groups swap with it.
        pass(&mut encoder, 0, &|p| {
            p.set_pipeline(&kernels.start);
            p.dispatch_workgroups(tw.div_ceil(wx), th.div_ceil(wy), depth);
        });
        let args = |encoder: &mut wgpu::CommandEncoder, side: usize| {
            pass(encoder, side, &|p| {
                p.set_bind_group(2, &self.args_group, &[]);
                p.set_pipeline(&self.args);
                p.dispatch_workgroups(1, 1, 1);
            })
        };
        args(&mut encoder, 0);
        let mut side = 1;
        // What the start made to trace (the light pass: its light points seen by the camera).
        pass(&mut encoder, side, &|p| {
            p.set_pipeline(&kernels.trace);
            p.dispatch_workgroups_indirect(&self.args_buffer, 12);
        });
        let bounces = if max_depth >= 0 { (max_depth as u32).min(MAX_BOUNCES) } else { MAX_BOUNCES };
        let mut bounce = 0;
        while bounce < bounces {
            let chunk =
                if bounces <= 2 * BOUNCES_PER_CHECK { bounces } else { BOUNCES_PER_CHECK.min(bounces - bounce) };
            for _ in 0..chunk {
                pass(&mut encoder, side, &|p| {
                    p.set_pipeline(&kernels.extend);
                    p.dispatch_workgroups_indirect(&self.args_buffer, 0);
                    p.set_pipeline(&kernels.shade);
                    p.dispatch_workgroups_indirect(&self.args_buffer, 0);
                });
                // The survivors become the next bounce's queue in, the shadow rays made
                // those to trace now.
                args(&mut encoder, side);
                side ^= 1;
                pass(&mut encoder, side, &|p| {
                    p.set_pipeline(&kernels.trace);
                    p.dispatch_workgroups_indirect(&self.args_buffer, 12);
                });
            }
            bounce += chunk;
            if bounce < bounces {
                encoder.copy_buffer_to_buffer(&self.counts, 0, &self.counts_readback, 0, 16);
                let done = std::mem::replace(&mut encoder, device.create_command_encoder(&Default::default()));
                queue.submit([done.finish()]);
                let alive = self.alive(device)?;
                if alive == 0 {
                    break;
                }
                if alive.saturating_mul(TAIL_SHARE) < tw * th * depth {
                    pass(&mut encoder, side, &|p| {
                        p.set_pipeline(&kernels.tail);
                        p.dispatch_workgroups_indirect(&self.args_buffer, 0);
                    });
                    break;
                }
            }
        }
        if let Some(finish) = &kernels.finish {
            pass(&mut encoder, side, &|p| {
                p.set_pipeline(finish);
                p.dispatch_workgroups(tw.div_ceil(wx), th.div_ceil(wy), depth);
            });
        }
        queue.submit([encoder.finish()]);
        Ok(())
    }

    /// Paths still alive after the last bounce submitted (read back from the counts).
    fn alive(&self, device: &wgpu::Device) -> Result<u32, GpuError> {
        let slice = self.counts_readback.slice(..);
        slice.map_async(wgpu::MapMode::Read, |_| {});
        crate::wait(device)?;
        let alive = {
            let data = slice.get_mapped_range().map_err(|e| GpuError::Readback(e.to_string()))?;
            bytemuck::cast_slice::<u8, u32>(&data)[0]
        };
        self.counts_readback.unmap();
        Ok(alive)
    }
}
