//! Which device Cycles renders on (`[render] device`). The worker asks
//! Blender which GPU devices each backend sees
//! (`blender_scripts/render.py: cycles_gpu_devices`) and [`resolve`] picks
//! one here, in Rust, so the choice is testable without a GPU; Blender only
//! switches to it and the sequence records what was used.
//!
//! The device only changes how pixels are computed, never what is planned:
//! it enters no random stream and no plan, so a seed gives the same labels
//! and camera paths on every device.

use super::engine::Engine;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// `[render] device`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Device {
    /// The first GPU backend Blender reports ([`AUTO_ORDER`]), else the CPU.
    #[default]
    Auto,
    Cpu,
    Cuda,
    Optix,
    Hip,
    Oneapi,
    Metal,
}

/// GPU backends in the order `auto` tries them: OptiX before CUDA because
/// it drives the same NVIDIA cards with their ray-tracing cores.
pub const AUTO_ORDER: [Device; 5] = [
    Device::Optix,
    Device::Cuda,
    Device::Hip,
    Device::Oneapi,
    Device::Metal,
];

/// What a non-Cycles engine's records say: Workbench and EEVEE draw through
/// Blender's own GPU module, which `device` does not choose.
pub const GPU_MODULE: &str = "gpu_module";

impl Device {
    /// The name used in configs and records (`cpu`, `optix`, ...).
    pub fn name(self) -> &'static str {
        match self {
            Device::Auto => "auto",
            Device::Cpu => "cpu",
            Device::Cuda => "cuda",
            Device::Optix => "optix",
            Device::Hip => "hip",
            Device::Oneapi => "oneapi",
            Device::Metal => "metal",
        }
    }

    /// Whether it names one GPU backend.
    pub fn is_gpu(self) -> bool {
        !matches!(self, Device::Auto | Device::Cpu)
    }
}

/// Devices per GPU backend name, as Blender reported them (empty lists for
/// backends this machine or this Blender build lacks).
pub type Reported = BTreeMap<String, Vec<String>>;

/// The device a worker renders on, and a line for the log when `auto` fell
/// back to the CPU.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Resolved {
    pub used: String,
    pub note: Option<String>,
}

/// A named GPU backend that Blender does not offer: the run cannot render
/// as configured, so it stops instead of retrying every sequence.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "[render] device = \"{requested}\": Blender reports no {requested} device (it reports {}); \
     choose device = \"auto\" or \"cpu\", or check the GPU driver",
    describe(.reported)
)]
pub struct DeviceUnavailable {
    pub requested: String,
    pub reported: Reported,
}

/// Whether the worker must ask Blender for its GPU devices before
/// [`resolve`]: only Cycles with `auto` or a named GPU (the query loads the
/// GPU drivers, which `cpu` should not need).
pub fn needs_query(engine: Engine, requested: Device) -> bool {
    engine == Engine::Cycles && requested != Device::Cpu
}

/// Picks the device for `requested` from what Blender reported.
pub fn resolve(
    engine: Engine,
    requested: Device,
    reported: &Reported,
) -> Result<Resolved, DeviceUnavailable> {
    let has = |d: Device| reported.get(d.name()).is_some_and(|v| !v.is_empty());
    let used = |d: Device| Resolved {
        used: d.name().to_string(),
        note: None,
    };
    if engine != Engine::Cycles {
        return Ok(Resolved {
            used: GPU_MODULE.to_string(),
            note: None,
        });
    }
    match requested {
        Device::Cpu => Ok(used(Device::Cpu)),
        Device::Auto => Ok(match AUTO_ORDER.into_iter().find(|d| has(*d)) {
            Some(d) => used(d),
            None => Resolved {
                used: Device::Cpu.name().to_string(),
                note: Some(format!(
                    "[render] device = \"auto\": Blender reports no GPU device ({}); \
                     rendering on the CPU",
                    describe(reported)
                )),
            },
        }),
        gpu if has(gpu) => Ok(used(gpu)),
        gpu => Err(DeviceUnavailable {
            requested: gpu.name().to_string(),
            reported: reported.clone(),
        }),
    }
}

/// `optix: NVIDIA A100; cuda: none; ...` for messages.
fn describe(reported: &Reported) -> String {
    if reported.is_empty() {
        return "no GPU backend".to_string();
    }
    let each: Vec<String> = reported
        .iter()
        .map(|(backend, devices)| match devices.is_empty() {
            true => format!("{backend}: none"),
            false => format!("{backend}: {}", devices.join(", ")),
        })
        .collect();
    each.join("; ")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn reported(with: &[(&str, &str)]) -> Reported {
        let mut r: Reported = AUTO_ORDER
            .iter()
            .map(|d| (d.name().to_string(), Vec::new()))
            .collect();
        for (backend, device) in with {
            r.insert(backend.to_string(), vec![device.to_string()]);
        }
        r
    }

    #[test]
    fn auto_without_a_gpu_falls_back_to_the_cpu_with_a_note() {
        let r = resolve(Engine::Cycles, Device::Auto, &reported(&[])).unwrap();
        assert_eq!(r.used, "cpu");
        let note = r.note.unwrap();
        assert!(
            note.contains("no GPU device") && note.contains("cuda: none"),
            "{note}"
        );
    }

    #[test]
    fn auto_prefers_optix_to_cuda_and_cpu_asks_nothing() {
        let both = reported(&[("cuda", "RTX"), ("optix", "RTX")]);
        let r = resolve(Engine::Cycles, Device::Auto, &both).unwrap();
        assert_eq!((r.used.as_str(), r.note), ("optix", None));
        let hip = resolve(Engine::Cycles, Device::Auto, &reported(&[("hip", "W7900")])).unwrap();
        assert_eq!(hip.used, "hip");
        assert!(!needs_query(Engine::Cycles, Device::Cpu));
        assert!(needs_query(Engine::Cycles, Device::Auto));
        assert!(!needs_query(Engine::Workbench, Device::Auto));
        let cpu = resolve(Engine::Cycles, Device::Cpu, &Reported::new()).unwrap();
        assert_eq!(cpu.used, "cpu");
    }

    #[test]
    fn a_named_backend_blender_lacks_is_an_error_naming_both() {
        let r = reported(&[("cuda", "RTX 4090")]);
        assert_eq!(
            resolve(Engine::Cycles, Device::Cuda, &r).unwrap().used,
            "cuda"
        );
        let e = resolve(Engine::Cycles, Device::Hip, &r).unwrap_err();
        let text = e.to_string();
        assert!(text.contains("device = \"hip\""), "{text}");
        assert!(
            text.contains("cuda: RTX 4090") && text.contains("hip: none"),
            "{text}"
        );
    }

    #[test]
    fn other_engines_record_the_gpu_module() {
        let r = resolve(Engine::Workbench, Device::Auto, &Reported::new()).unwrap();
        assert_eq!(r.used, GPU_MODULE);
    }
}
