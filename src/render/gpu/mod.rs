//! The GPU renderer: the composite ray march of [`super::composite`] (and so the single-field
//! march of [`crate::field::march`], a composite of one field in place) as a wgpu compute
//! shader (`march.wgsl`, a sample's colour in `colour.wgsl`), one invocation a ray, in the same
//! f32 arithmetic in the same order, so that its frames match the CPU's to rounding
//! (`tests/gpu_parity.rs`, on Mesa's lavapipe). A ray whose loops the device ended early (Mesa
//! llvmpipe's loop budget, see `colour.wgsl`) makes the frame an error, never a wrong pixel.
//!
//! - [`Gpu::open`] finds an adapter ([`DeviceChoice`]: `auto` takes hardware only, `gpu` a
//!   software Vulkan device too; `OBJNERF_GPU_ADAPTER` picks one by name).
//! - [`Gpu::upload`] packs a composite's fields into storage buffers once ([`upload`]);
//!   [`GpuComposite::render_frame`] and [`GpuComposite::render_view`] draw frames from it.
//! - [`renderer`] is what the commands call: a [`FrameRenderer`] on the device asked for, and a
//!   [`DeviceUsed`] saying which it is and why.
//!
//! Rays are made on the CPU ([`RayCamera::ray_through`], exactly as the CPU renderer makes
//! them) and uploaded: a 1920x1080 frame's are 33 MB, and any camera model works.
//!
//! A GPU trainer would reuse the forward pass as it is: `march.wgsl`'s `start`/`advance`/
//! `visit` are the forward of `field::march::forward` with every kept sample at hand (what the
//! backward needs: `t`, alpha, transmittance, colour), and [`upload`]'s buffers are the field's
//! own layout (`Grid::data`, the brick index, occupancy), so gradients laid out like
//! `Grid::data` could be scattered into a buffer of the same shape.

pub mod device;
mod upload;

pub use device::{open_device, renderer, DeviceChoice, DeviceUsed, FrameRenderer};
pub use upload::MAX_LAYERS;

use super::composite::{Composite, Frame, Layer};
use crate::edit::Similarity;
use crate::error::{Error, Result};
use crate::field::eval::Rendered;
use crate::field::{Field, RayCamera, RenderOptions};
use glam::Vec3;
use upload::{layer_records, pack, Packed};
use wgpu::util::DeviceExt;

/// An adapter with the march's pipeline.
pub struct Gpu {
    device: wgpu::Device,
    queue: wgpu::Queue,
    pipeline: wgpu::ComputePipeline,
    info: wgpu::AdapterInfo,
    max_binding: u64,
}

/// One ray's result, as the shader writes it.
#[derive(Clone, Copy, Debug, Default)]
pub struct GpuRay {
    pub rgb: [f32; 3],
    pub alpha: f32,
    /// Distance along the world ray where the opacity reaches 1/2 (+inf: never).
    pub t_half: f32,
    /// sum w t (the single-field renderer's unnormalised depth).
    pub depth: f32,
    pub index: u8,
}

/// Workgroup size of `march.wgsl`'s entry point.
const GROUP: u32 = 64;
/// Most workgroups along one dispatch axis (WebGPU's limit).
const MAX_GROUPS: u32 = 65535;

impl Gpu {
    /// The adapter's name and driver, e.g. "llvmpipe (LLVM 15.0.6, 256 bits) (Vulkan, Cpu)".
    pub fn name(&self) -> String {
        let i = &self.info;
        format!("{} ({:?}, {:?})", i.name, i.backend, i.device_type)
    }

    /// Whether this is a software device (a CPU implementation such as lavapipe).
    pub fn is_software(&self) -> bool {
        self.info.device_type == wgpu::DeviceType::Cpu
    }

    /// Upload the fields of `c` (once; frames are then drawn from them).
    pub fn upload<'a>(&'a self, c: &'a Composite<'a>) -> Result<GpuComposite<'a>> {
        let packed = pack(c)?;
        let bytes = (packed.vals.len() * 4).max(packed.words.len() * 4) as u64;
        if bytes > self.max_binding {
            return Err(Error::invalid(format!(
                "the fields need a {} MiB buffer; {} binds at most {} MiB",
                bytes >> 20,
                self.name(),
                self.max_binding >> 20
            )));
        }
        let storage = |label: &str, contents: &[u8]| {
            self.device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents,
                    usage: wgpu::BufferUsages::STORAGE,
                })
        };
        // A buffer may not be empty.
        let mut vals = packed.vals.clone();
        vals.push(0.0);
        let mut words = packed.words.clone();
        words.push(0);
        let vals = storage("field values", bytes_of(&vals));
        let words = storage("field words", bytes_of(&words));
        Ok(GpuComposite {
            gpu: self,
            composite: c,
            packed,
            vals,
            words,
        })
    }

    /// Run the march for the world rays from `o` along `dirs` (unit) through `c`'s layers.
    fn march(&self, g: &GpuComposite, o: Vec3, dirs: &[Vec3]) -> Result<Vec<GpuRay>> {
        let n = dirs.len();
        if n == 0 {
            return Ok(Vec::new());
        }
        let c = g.composite;
        let dev = &self.device;
        let layers = layer_records(c, &g.packed, o);
        let r = &c.render;
        let params: [u32; 8] = [
            n as u32,
            c.layers.len() as u32,
            r.alpha_thresh.to_bits(),
            r.term_thresh.to_bits(),
            c.background[0].to_bits(),
            c.background[1].to_bits(),
            c.background[2].to_bits(),
            0,
        ];
        let rays: Vec<f32> = dirs.iter().flat_map(|d| [d.x, d.y, d.z, 0.0]).collect();
        let out_bytes = (n * 8 * 4) as u64;
        if (rays.len() * 4) as u64 > self.max_binding || out_bytes > self.max_binding {
            return Err(Error::invalid(format!(
                "{n} rays in one frame do not fit {}'s buffers",
                self.name()
            )));
        }
        let init = |label: &str, contents: &[u8], usage| {
            dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage,
            })
        };
        let mut layer_words = layers;
        layer_words.push(0);
        let params_buf = init("params", bytes_of(&params), wgpu::BufferUsages::UNIFORM);
        let layers_buf = init(
            "layers",
            bytes_of(&layer_words),
            wgpu::BufferUsages::STORAGE,
        );
        let rays_buf = init("rays", bytes_of(&rays), wgpu::BufferUsages::STORAGE);
        let out = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("ray results"),
            size: out_bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let staging = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("ray results, read back"),
            size: out_bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let entries = [
            params_buf.as_entire_binding(),
            layers_buf.as_entire_binding(),
            g.vals.as_entire_binding(),
            g.words.as_entire_binding(),
            rays_buf.as_entire_binding(),
            out.as_entire_binding(),
        ];
        let entries: Vec<wgpu::BindGroupEntry> = entries
            .into_iter()
            .enumerate()
            .map(|(i, resource)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource,
            })
            .collect();
        let bind = dev.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("march"),
            layout: &self.pipeline.get_bind_group_layout(0),
            entries: &entries,
        });
        let groups = (n as u32).div_ceil(GROUP);
        let (gx, gy) = (groups.min(MAX_GROUPS), groups.div_ceil(MAX_GROUPS));
        let mut enc = dev.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
        }
        enc.copy_buffer_to_buffer(&out, 0, &staging, 0, out_bytes);
        self.queue.submit([enc.finish()]);
        let raw = self.read(&staging)?;
        let cut = raw.chunks_exact(8).filter(|w| w[7] != 0).count();
        if cut > 0 {
            return Err(gpu_error(
                self,
                format!(
                    "the device ended the march's loops early on {cut} of {n} rays (a \
                     software device's limit on loop iterations, as Mesa llvmpipe's 65535 a \
                     batch of rays); render these fields on the CPU (--device cpu)"
                ),
            ));
        }
        Ok(raw
            .chunks_exact(8)
            .map(|w| {
                let f = |i: usize| f32::from_bits(w[i]);
                GpuRay {
                    rgb: [f(0), f(1), f(2)],
                    alpha: f(3),
                    t_half: if f(4) < 0.0 { f32::INFINITY } else { f(4) },
                    depth: f(5),
                    index: w[6].min(255) as u8,
                }
            })
            .collect())
    }

    /// Map `buf` and copy its words out (blocking).
    fn read(&self, buf: &wgpu::Buffer) -> Result<Vec<u32>> {
        let slice = buf.slice(..);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        // wgpu gives up a wait after 60 s, which a large frame on a software device (lavapipe)
        // can take, the machine loaded; wait on, up to an hour.
        let mut waits = 0;
        while let Err(e) = self.device.poll(wgpu::PollType::Wait) {
            waits += 1;
            if waits == 60 {
                return Err(gpu_error(self, format!("waiting for the frame: {e}")));
            }
        }
        rx.recv()
            .map_err(|e| gpu_error(self, e.to_string()))?
            .map_err(|e| gpu_error(self, format!("reading the frame back: {e}")))?;
        let words = {
            let data = slice.get_mapped_range();
            data.chunks_exact(4)
                .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                .collect()
        };
        buf.unmap();
        Ok(words)
    }
}

fn gpu_error(g: &Gpu, msg: String) -> Error {
    Error::external(format!("GPU {}", g.name()), msg)
}

fn bytes_of<T: Copy>(v: &[T]) -> &[u8] {
    // f32 and u32 only (plain 4-byte values, no padding).
    debug_assert_eq!(std::mem::size_of::<T>(), 4);
    // SAFETY: T is f32 or u32: every byte is initialised and any alignment of u8 holds.
    unsafe { std::slice::from_raw_parts(v.as_ptr() as *const u8, std::mem::size_of_val(v)) }
}

/// A composite's fields on the GPU.
pub struct GpuComposite<'a> {
    gpu: &'a Gpu,
    composite: &'a Composite<'a>,
    packed: Packed,
    vals: wgpu::Buffer,
    words: wgpu::Buffer,
}

impl GpuComposite<'_> {
    /// The frame [`super::composite::render_frame`] draws.
    pub fn render_frame(&self, cam: &RayCamera) -> Result<Frame> {
        let (w, h) = (cam.width, cam.height);
        let n = w * h;
        let dirs: Vec<Vec3> = (0..n).map(|i| cam.ray(i).1).collect();
        let rays = self.gpu.march(self, cam.center(), &dirs)?;
        let mut f = Frame {
            width: w,
            height: h,
            rgb: Vec::with_capacity(n as usize),
            alpha: Vec::with_capacity(n as usize),
            depth: Vec::with_capacity(n as usize),
            index: Vec::with_capacity(n as usize),
        };
        for (i, r) in rays.iter().enumerate() {
            f.rgb.push(r.rgb);
            f.alpha.push(r.alpha);
            f.depth.push(r.t_half / cam.ray_scale(i as u32));
            f.index.push(r.index);
        }
        Ok(f)
    }

    /// The view [`crate::field::eval::render_view`] draws (a composite of one field in place,
    /// over its background, `render.pixel_samples` rays a pixel).
    pub fn render_view(&self, cam: &RayCamera) -> Result<Rendered> {
        let (w, h) = (cam.width, cam.height);
        let k = self.composite.render.pixel_samples.max(1);
        let inv = 1.0 / (k * k) as f32;
        let mut dirs = Vec::with_capacity((w * h * k * k) as usize);
        for idx in 0..w * h {
            for j in 0..k {
                for i in 0..k {
                    let at = [(i as f32 + 0.5) / k as f32, (j as f32 + 0.5) / k as f32];
                    dirs.push(cam.ray_through(idx, at).1);
                }
            }
        }
        let rays = self.gpu.march(self, cam.center(), &dirs)?;
        let mut out = Rendered::with_capacity(w, h);
        for px in rays.chunks_exact((k * k) as usize) {
            let (mut alpha, mut depth, mut rgb) = (0.0, 0.0, [0.0f32; 3]);
            for r in px {
                alpha += r.alpha * inv;
                depth += r.depth * inv;
                (0..3).for_each(|c| rgb[c] += r.rgb[c] * inv);
            }
            out.alpha.push(alpha);
            out.depth
                .push(if alpha > 1e-3 { depth / alpha } else { 0.0 });
            out.rgb.push(rgb);
        }
        Ok(out)
    }
}

/// A composite of `field` alone, in place, over `bg`: what `render_view` draws.
pub fn single<'a>(field: &'a Field, opt: &RenderOptions, bg: [f32; 3]) -> Composite<'a> {
    Composite {
        layers: vec![Layer::new(field, &Similarity::IDENTITY, 0)],
        background: bg,
        render: *opt,
    }
}
