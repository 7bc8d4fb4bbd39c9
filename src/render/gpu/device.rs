//! Which device draws: `--device auto|cpu|gpu`, the adapter search, and a frame renderer on
//! either.

use super::{Gpu, GpuComposite};
use crate::error::{Error, Result};
use crate::field::eval::{render_view, Rendered};
use crate::field::RayCamera;
use crate::render::composite::{render_frame, Composite, Frame};
use serde::Serialize;

/// Where frames are drawn.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DeviceChoice {
    /// A hardware GPU when there is one (a software Vulkan device does not count), else the CPU.
    #[default]
    Auto,
    Cpu,
    /// A GPU adapter, hardware preferred, a software one (lavapipe) accepted; none is an error.
    Gpu,
}

impl std::str::FromStr for DeviceChoice {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "auto" => Ok(DeviceChoice::Auto),
            "cpu" => Ok(DeviceChoice::Cpu),
            "gpu" => Ok(DeviceChoice::Gpu),
            _ => Err(format!("'{s}': the device is auto, cpu or gpu")),
        }
    }
}

/// Which device drew, and why (for the report).
#[derive(Clone, Debug, Serialize)]
pub struct DeviceUsed {
    /// "cpu" or "gpu".
    pub device: &'static str,
    /// The GPU adapter, when one drew.
    pub adapter: Option<String>,
    /// Why `auto` took the CPU (no hardware adapter, or what the GPU renderer cannot draw).
    pub note: Option<String>,
}

impl DeviceUsed {
    fn cpu(note: Option<String>) -> DeviceUsed {
        DeviceUsed {
            device: "cpu",
            adapter: None,
            note,
        }
    }

    /// One line for a person, e.g. "gpu: NVIDIA ... (Vulkan, DiscreteGpu)".
    pub fn describe(&self) -> String {
        match (&self.adapter, &self.note) {
            (Some(a), _) => format!("{}: {a}", self.device),
            (None, Some(n)) => format!("{} ({n})", self.device),
            (None, None) => self.device.to_string(),
        }
    }
}

/// The backends searched for an adapter.
const BACKENDS: wgpu::Backends = wgpu::Backends::VULKAN
    .union(wgpu::Backends::METAL)
    .union(wgpu::Backends::DX12);

/// Names a person reads for [`BACKENDS`].
const BACKEND_NAMES: &str = "Vulkan, Metal, DX12";

/// Picks an adapter by a part of its name (e.g. `llvmpipe`), software ones included.
pub const ADAPTER_ENV: &str = "OBJNERF_GPU_ADAPTER";

fn rank(t: wgpu::DeviceType) -> u8 {
    match t {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Other => 3,
        wgpu::DeviceType::Cpu => 4,
    }
}

impl Gpu {
    /// The best adapter (discrete, integrated, virtual, other, then software when
    /// `software_ok`), or the one `OBJNERF_GPU_ADAPTER` names; an error lists what was found.
    pub fn open(software_ok: bool) -> Result<Gpu> {
        let instance = wgpu::Instance::new(&wgpu::InstanceDescriptor {
            backends: BACKENDS,
            flags: wgpu::InstanceFlags::empty(),
            ..Default::default()
        });
        let mut adapters = instance.enumerate_adapters(BACKENDS);
        let wanted = std::env::var(ADAPTER_ENV).ok().filter(|s| !s.is_empty());
        let found: Vec<String> = adapters
            .iter()
            .map(|a| {
                let i = a.get_info();
                format!("{} ({:?}, {:?})", i.name, i.backend, i.device_type)
            })
            .collect();
        adapters.retain(|a| {
            let i = a.get_info();
            match &wanted {
                Some(w) => i.name.to_lowercase().contains(&w.to_lowercase()),
                None => software_ok || i.device_type != wgpu::DeviceType::Cpu,
            }
        });
        adapters.sort_by_key(|a| rank(a.get_info().device_type));
        let Some(adapter) = adapters.into_iter().next() else {
            let looked = match &wanted {
                Some(w) => format!("adapter named like '{w}' ({ADAPTER_ENV})"),
                None if software_ok => "GPU adapter".to_string(),
                None => "hardware GPU adapter (a software one does not count)".to_string(),
            };
            let seen = if found.is_empty() {
                "none".to_string()
            } else {
                found.join("; ")
            };
            return Err(Error::external(
                "GPU",
                format!(
                    "found no {looked} through {BACKEND_NAMES}; adapters found: {seen} (on \
                     Linux without a GPU, Mesa's lavapipe is Debian's mesa-vulkan-drivers)"
                ),
            ));
        };
        let info = adapter.get_info();
        let limits = adapter.limits();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("objnerf"),
            required_features: wgpu::Features::empty(),
            required_limits: limits.clone(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        }))
        .map_err(|e| Error::external(format!("GPU {}", info.name), e.to_string()))?;
        device.push_error_scope(wgpu::ErrorFilter::Validation);
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("march.wgsl"),
            // One module from two files (WGSL has no includes): the march and the colour.
            source: wgpu::ShaderSource::Wgsl(
                concat!(include_str!("march.wgsl"), include_str!("colour.wgsl")).into(),
            ),
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("march"),
            layout: None,
            module: &module,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
        if let Some(e) = pollster::block_on(device.pop_error_scope()) {
            return Err(Error::external(
                format!("GPU {}", info.name),
                format!("the march shader does not build: {e}"),
            ));
        }
        let max_binding =
            (limits.max_storage_buffer_binding_size as u64).min(limits.max_buffer_size);
        Ok(Gpu {
            device,
            queue,
            pipeline,
            info,
            max_binding,
        })
    }
}

/// Frames drawn on the CPU or the GPU.
pub enum FrameRenderer<'a> {
    Cpu(&'a Composite<'a>),
    Gpu(GpuComposite<'a>),
}

impl FrameRenderer<'_> {
    /// [`render_frame`]'s frame.
    pub fn render_frame(&self, cam: &RayCamera) -> Result<Frame> {
        match self {
            FrameRenderer::Cpu(c) => Ok(render_frame(c, cam)),
            FrameRenderer::Gpu(g) => g.render_frame(cam),
        }
    }

    /// [`render_view`]'s view of the composite's only field (see [`super::single`]).
    pub fn render_view(&self, cam: &RayCamera) -> Result<Rendered> {
        match self {
            FrameRenderer::Cpu(c) => {
                Ok(render_view(c.layers[0].field, &c.render, cam, c.background))
            }
            FrameRenderer::Gpu(g) => g.render_view(cam),
        }
    }
}

/// The GPU asked for (`gpu` accepts a software adapter; `auto` does not); `None` for the CPU,
/// with why in the note.
pub fn open_device(choice: DeviceChoice) -> Result<(Option<Gpu>, DeviceUsed)> {
    match choice {
        DeviceChoice::Cpu => Ok((None, DeviceUsed::cpu(None))),
        DeviceChoice::Gpu => {
            let g = Gpu::open(true)?;
            let used = DeviceUsed {
                device: "gpu",
                adapter: Some(g.name()),
                note: None,
            };
            Ok((Some(g), used))
        }
        DeviceChoice::Auto => match Gpu::open(false) {
            Ok(g) => {
                let used = DeviceUsed {
                    device: "gpu",
                    adapter: Some(g.name()),
                    note: None,
                };
                Ok((Some(g), used))
            }
            Err(e) => Ok((None, DeviceUsed::cpu(Some(e.to_string())))),
        },
    }
}

/// A renderer of `c` on `gpu` when there is one and it can draw `c` (with `auto`, the CPU when
/// it cannot, the reason added to `used`; with `gpu`, an error).
pub fn renderer<'a>(
    c: &'a Composite<'a>,
    gpu: Option<&'a Gpu>,
    choice: DeviceChoice,
    used: &mut DeviceUsed,
) -> Result<FrameRenderer<'a>> {
    let Some(g) = gpu else {
        return Ok(FrameRenderer::Cpu(c));
    };
    match g.upload(c) {
        Ok(up) => Ok(FrameRenderer::Gpu(up)),
        Err(e) if choice == DeviceChoice::Auto => {
            *used = DeviceUsed::cpu(Some(format!("{}: {e}", g.name())));
            Ok(FrameRenderer::Cpu(c))
        }
        Err(e) => Err(e),
    }
}
