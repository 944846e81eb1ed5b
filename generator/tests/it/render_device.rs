//! `[render] device`: an unknown name is refused by the config parser;
//! `auto` on a machine without a GPU renders on the CPU, says so once and
//! records it; `cpu` and `auto` give the same plans and labels; a GPU
//! backend Blender lacks stops the run naming it; and, where Blender
//! reports a CUDA or OptiX device, Cycles renders on it (skipped without
//! one, a failure under `GRASP_REQUIRE_GPU=1`). Cycles, 1 sample, 16-32 px.

use crate::render_common::*;
use generator::config::GeneratorConfig;
use generator::render::{render, Device, Engine, RenderConfig};
use grasp_test_support::prerequisite::{check, REQUIRE_GPU_ENV};
use grasp_test_support::program::Finished;
use std::path::{Path, PathBuf};
use std::sync::Arc;

fn cycles(device: Device) -> RenderConfig {
    RenderConfig {
        engine: Engine::Cycles,
        device,
        samples: 1,
        ..Default::default()
    }
}

#[test]
fn an_unknown_or_misplaced_device_is_refused_naming_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("gpu.toml");
    std::fs::write(&path, "[render]\ndevice = \"vulkan\"\n").unwrap();
    let e = format!(
        "{:#}",
        anyhow::Error::from(GeneratorConfig::load(&path).unwrap_err())
    );
    assert!(e.contains("gpu.toml"), "{e}");
    assert!(e.contains("device") && e.contains("vulkan"), "{e}");
    assert!(e.contains("optix") && e.contains("cpu"), "{e}");
    std::fs::write(
        &path,
        "[render]\nengine = \"workbench\"\ndevice = \"cuda\"\n",
    )
    .unwrap();
    let e = format!(
        "{:#}",
        anyhow::Error::from(GeneratorConfig::load(&path).unwrap_err())
    );
    assert!(e.contains("[render] device = \"cuda\""), "{e}");
    for name in ["auto", "cpu", "cuda", "optix", "hip", "oneapi", "metal"] {
        std::fs::write(&path, format!("[render]\ndevice = \"{name}\"\n")).unwrap();
        let c = GeneratorConfig::load(&path).unwrap();
        assert_eq!(c.render.device.name(), name);
    }
}

/// A tiny Cycles config of the built-in mug through the real planner.
fn config(dir: &Path, device: &str) -> PathBuf {
    let text = format!(
        "[dataset]\nsequences_per_pair = 1\nconditions = [\"default\"]\n\
         objects = [\"025_mug\"]\n\n[plan.camera]\nresolution = [24, 24]\n\n\
         [plan.trajectory]\nfps = 1.0\n\n[render]\nengine = \"cycles\"\nsamples = 1\n\
         device = \"{device}\"\n"
    );
    let path = dir.join(format!("{device}.toml"));
    std::fs::write(&path, text).unwrap();
    path
}

/// `device = "cpu"` and `"auto"` plan the same sequences with the same
/// labels; without a GPU, `auto` logs its fallback once, records `cpu`, and
/// gives the very frames `cpu` does. Each dataset verifies against the
/// other's config: the device may differ within a dataset.
#[test]
fn cpu_and_auto_give_the_same_plans_and_labels() {
    if !have_blender() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let mut outs = Vec::new();
    let mut logs = Vec::new();
    for device in ["cpu", "auto"] {
        let (cfg, out) = (config(dir.path(), device), dir.path().join(device));
        let Finished { stdout, stderr, .. } = grasp_gen().ok([
            "render",
            "--config",
            cfg.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--workers",
            "2",
            "--no-progress",
        ]);
        assert!(stdout.contains("rendered on: "), "{stdout}");
        logs.push((stdout, stderr));
        outs.push((cfg, out));
    }
    let (cpu, auto) = (records(&outs[0].1), records(&outs[1].1));
    assert!(cpu.len() >= 2, "the mug has several parts: {}", cpu.len());
    assert_eq!(cpu.len(), auto.len());
    for ((path, a), (other, b)) in cpu.iter().zip(&auto) {
        assert_eq!(path, other);
        assert!(a.plan == b.plan, "{}: plans differ", path.display());
        assert_eq!(a.frame_files, b.frame_files);
        assert_eq!(a.render["device"], "cpu");
        assert_eq!(b.render["device"], "auto");
        assert_eq!(a.render_device().as_deref(), Some("cpu"));
    }
    let auto_used = auto[0].1.render_device().unwrap();
    let fallback = "[render] device = \"auto\": Blender reports no GPU device";
    let (auto_out, auto_err) = &logs[1];
    if auto_used == "cpu" {
        assert_eq!(auto_err.matches(fallback).count(), 1, "{auto_err}");
        assert!(auto_err.contains("rendering on the CPU"), "{auto_err}");
        assert!(auto_out.contains("rendered on: cpu"), "{auto_out}");
        // The same device, so the same pixels: the fallback is the CPU path.
        let (a, b) = (tree(&outs[0].1), tree(&outs[1].1));
        assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
        for (name, bytes) in a.iter().filter(|(n, _)| n.ends_with(".png")) {
            assert!(bytes == &b[name], "{name} differs");
        }
    } else {
        assert!(!auto_err.contains(fallback), "{auto_err}");
    }
    assert!(!logs[0].1.contains(fallback), "cpu asks for no GPU");
    for ((_, data), (cfg, _)) in outs.iter().zip(outs.iter().rev()) {
        let stdout = grasp_gen()
            .ok([
                "dataset",
                "verify",
                data.to_str().unwrap(),
                "--config",
                cfg.to_str().unwrap(),
            ])
            .stdout;
        assert!(stdout.trim_end().ends_with("ok"), "{stdout}");
    }
}

/// Metal exists on no Linux machine: naming it stops the run before any
/// sequence, once, with what Blender reported, instead of retrying every
/// sequence.
#[test]
#[cfg(target_os = "linux")]
fn a_gpu_backend_blender_lacks_stops_the_run_naming_it() {
    if !have_blender() {
        return;
    }
    let out = tempfile::tempdir().unwrap();
    let s = render(
        Arc::new(source(3, 2, 16)),
        &cycles(Device::Metal),
        &options(out.path(), 2),
    )
    .unwrap();
    let fatal = s.fatal.clone().expect("the run stops");
    assert!(fatal.contains("[render] device = \"metal\""), "{fatal}");
    assert!(fatal.contains("Blender reports no metal device"), "{fatal}");
    assert!(
        fatal.contains("cuda:"),
        "names what Blender reported: {fatal}"
    );
    assert_eq!((s.rendered, s.retries), (0, 0), "{s:?}");
}

/// Renders on each of CUDA and OptiX that Blender reports: the record names
/// it, the plans are the CPU's and the frames look like the CPU's (another
/// device computes the same light paths in another order, so pixels may
/// differ a little, not more).
#[test]
fn a_cuda_or_optix_gpu_renders_when_there_is_one() {
    if !have_blender() {
        return;
    }
    let src = Arc::new(source(2, 2, 32));
    let cpu_out = tempfile::tempdir().unwrap();
    let probe = render(
        src.clone(),
        &cycles(Device::Auto),
        &options(cpu_out.path(), 1),
    )
    .unwrap();
    let test = "a_cuda_or_optix_gpu_renders_when_there_is_one";
    let missing = match (&probe.device_note, probe.devices.contains("cpu")) {
        (Some(note), _) => Some(note.clone()),
        (None, true) => Some("auto rendered on the CPU".to_string()),
        (None, false) => None,
    };
    let mut rendered = Vec::new();
    let mut unavailable = Vec::new();
    if missing.is_none() {
        for device in [Device::Cuda, Device::Optix] {
            let out = tempfile::tempdir().unwrap();
            let s = render(src.clone(), &cycles(device), &options(out.path(), 1)).unwrap();
            match s.fatal {
                Some(why) => unavailable.push(why),
                None => {
                    assert_eq!(s.failed, vec![], "{device:?}");
                    rendered.push((device, out));
                }
            }
        }
    }
    let why = match (&missing, rendered.is_empty()) {
        (Some(m), _) => Some(m.clone()),
        (None, true) => Some(format!("no CUDA or OptiX device: {unavailable:?}")),
        (None, false) => None,
    };
    if !check(test, REQUIRE_GPU_ENV, why) {
        return;
    }
    let cpu_out = tempfile::tempdir().unwrap();
    render(
        src.clone(),
        &cycles(Device::Cpu),
        &options(cpu_out.path(), 1),
    )
    .unwrap();
    let cpu = records(cpu_out.path());
    for (device, out) in &rendered {
        let gpu = records(out.path());
        assert_eq!(gpu.len(), cpu.len());
        for ((path, a), (_, b)) in cpu.iter().zip(&gpu) {
            assert!(a.plan == b.plan);
            assert_eq!(b.render_device().as_deref(), Some(device.name()));
            let dir = path.parent().unwrap();
            for f in &a.frame_files {
                let x = image::open(cpu_out.path().join(dir).join(f))
                    .unwrap()
                    .to_rgb8();
                let y = image::open(out.path().join(dir).join(f)).unwrap().to_rgb8();
                assert_eq!(x.dimensions(), y.dimensions());
                let diff: f64 = x
                    .as_raw()
                    .iter()
                    .zip(y.as_raw())
                    .map(|(p, q)| (*p as f64 - *q as f64).abs())
                    .sum::<f64>()
                    / x.as_raw().len() as f64;
                eprintln!("{device:?} {f}: mean |GPU - CPU| = {diff:.2} levels");
                assert!(diff < 12.0, "{device:?} {f}: mean difference {diff:.2}");
            }
        }
    }
}
