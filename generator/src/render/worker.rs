//! The worker process (`grasp-gen worker`, hidden): embeds Python, imports
//! `bpy` once, builds the scene once, then renders the sequences the parent
//! sends until told to quit or its stdin closes.

use super::device::{self, Resolved};
use super::error::{PyFailure, RenderError, Result};
use super::parts::{read_exr, write_labels, PartLabeler};
use super::protocol::{MeshFiles, RenderRequest, Request, Response};
use super::{Device, Engine, World};
use crate::catalog::TriMesh;
use crate::dataset::error::chain;
use grasp_schema::dataset::{
    part_file_name, RenderCost, HEAD_CAMERA_FOLDER, WORLD_KEY, WRIST_CAMERA_FOLDER,
};
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use std::fs::File;
use std::io::{BufRead, Write};
use std::time::Instant;

/// Testing hook: when set to a path that does not exist yet, the worker
/// creates it and aborts right after its next render (so exactly one crash
/// happens across restarts).
pub const CRASH_ONCE_ENV: &str = "GRASP_GEN_WORKER_CRASH_ONCE";

pub fn run() -> Result<()> {
    crate::python::init(&[])?;
    let mut out = protocol_channel()?;
    let stdin = std::io::stdin();
    let mut lines = stdin.lock().lines();
    let Some(first) = lines.next() else {
        return Ok(());
    };
    let first = first.map_err(|source| RenderError::Stdin {
        what: "reading the init message",
        source,
    })?;
    let (worker, settings, device) = match init_worker(&first) {
        Ok(w) => w,
        Err(e) => {
            send(
                &mut out,
                &Response::Error {
                    id: None,
                    message: chain(&e),
                    fatal: matches!(e, RenderError::Device(_)),
                },
            )?;
            return Err(e);
        }
    };
    send(
        &mut out,
        &Response::Ready {
            pid: std::process::id(),
            device: device.used.clone(),
            note: device.note.clone(),
        },
    )?;
    for line in lines {
        let line = line.map_err(|source| RenderError::Stdin {
            what: "reading a request",
            source,
        })?;
        let request =
            serde_json::from_str::<Request>(&line).map_err(|source| RenderError::Json {
                what: "invalid request",
                source,
            })?;
        match request {
            Request::Quit => break,
            Request::Init { .. } => return Err(RenderError::Protocol("init sent twice")),
            Request::Render(req) => {
                let start = Instant::now();
                let reply = match render(&worker, &settings, &req) {
                    Ok(cost) => Response::Done {
                        id: req.id.clone(),
                        seconds: start.elapsed().as_secs_f64(),
                        peak_rss_kib: proc_status_kib("VmHWM:"),
                        rss_kib: proc_status_kib("VmRSS:"),
                        cost: RenderCost {
                            device: device.used.clone(),
                            ..cost
                        },
                    },
                    Err(e) => Response::Error {
                        id: Some(req.id.clone()),
                        message: chain(&e),
                        fatal: false,
                    },
                };
                crash_once_if_asked();
                send(&mut out, &reply)?;
            }
        }
    }
    Ok(())
}

/// Moves fd 1 away for the protocol and points fd 1 at stderr, so Blender's
/// prints never corrupt the JSON lines.
fn protocol_channel() -> Result<File> {
    let fd: i32 = Python::attach(|py| -> PyResult<i32> {
        // Die with the parent (Linux), so a killed `render` leaves no
        // orphan writing into the dataset: prctl(PR_SET_PDEATHSIG, SIGKILL).
        if cfg!(target_os = "linux") {
            let libc = py.import("ctypes")?.call_method1("CDLL", (py.None(),))?;
            libc.call_method1("prctl", (1, 9))?;
        }
        let os = py.import("os")?;
        let fd: i32 = os.call_method1("dup", (1,))?.extract()?;
        os.call_method1("dup2", (2, 1))?;
        Ok(fd)
    })
    .map_err(|e| RenderError::Blender {
        doing: "cannot redirect stdout".into(),
        source: PyFailure {
            message: e.to_string(),
        },
    })?;
    // SAFETY: `fd` was just created by dup() and is owned by nobody else.
    Ok(unsafe { <File as std::os::fd::FromRawFd>::from_raw_fd(fd) })
}

fn send(out: &mut File, response: &Response) -> Result<()> {
    let mut line = serde_json::to_string(response).map_err(|source| RenderError::Json {
        what: "a worker response",
        source,
    })?;
    line.push('\n');
    out.write_all(line.as_bytes())
        .and_then(|_| out.flush())
        .map_err(RenderError::Parent)
}

/// Peak resident set size of this process (0 where /proc is unavailable).
pub fn peak_rss_kib() -> u64 {
    proc_status_kib("VmHWM:")
}

/// A KiB field of /proc/self/status (`VmHWM:`, `VmRSS:`); 0 when unavailable.
fn proc_status_kib(field: &str) -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with(field))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|v| v.parse().ok())
        })
        .unwrap_or(0)
}

fn crash_once_if_asked() {
    if let Some(marker) = std::env::var_os(CRASH_ONCE_ENV) {
        let marker = std::path::PathBuf::from(marker);
        if !marker.exists() && std::fs::write(&marker, b"crashed").is_ok() {
            eprintln!("worker: aborting on purpose ({CRASH_ONCE_ENV})");
            std::process::abort();
        }
    }
}

/// A Python exception with its traceback, as text.
fn py_failure(e: PyErr) -> PyFailure {
    Python::attach(|py| {
        let tb = e
            .traceback(py)
            .and_then(|tb| tb.format().ok())
            .unwrap_or_default();
        PyFailure {
            message: format!("{tb}{e}"),
        }
    })
}

fn py_err(e: PyErr) -> RenderError {
    RenderError::Py(py_failure(e))
}

/// A Python call that failed while `doing` something.
fn blender(doing: impl Into<String>) -> impl FnOnce(PyErr) -> RenderError {
    let doing = doing.into();
    move |e| RenderError::Blender {
        doing,
        source: py_failure(e),
    }
}

/// `e`, about the step `what`.
fn step(what: impl Into<String>) -> impl FnOnce(RenderError) -> RenderError {
    let what = what.into();
    move |e| RenderError::Step {
        what,
        source: Box::new(e),
    }
}

/// A value of the render settings or a message that does not parse.
fn json(what: &'static str) -> impl FnOnce(serde_json::Error) -> RenderError {
    move |source| RenderError::Json { what, source }
}

fn json_to_py<'py>(py: Python<'py>, value: &impl serde::Serialize) -> Result<Bound<'py, PyAny>> {
    let text = serde_json::to_string(value).map_err(json("a value for Python"))?;
    py.import("json")
        .and_then(|json| json.call_method1("loads", (text,)))
        .map_err(py_err)
}

fn init_worker(line: &str) -> Result<(Py<PyAny>, serde_json::Value, Resolved)> {
    let Request::Init { geometry, settings } =
        serde_json::from_str::<Request>(line).map_err(json("invalid init message"))?
    else {
        return Err(RenderError::Protocol("the first message must be init"));
    };
    let world = world_of(&settings)?;
    crate::python::init(&["bpy", world.worker_module()])?;
    Python::attach(|py| {
        let module = py.import(world.worker_module()).map_err(py_err)?;
        let worker = module
            .getattr("Worker")
            .and_then(|cls| {
                cls.call1((
                    json_to_py(py, &geometry).map_err(to_pyerr)?,
                    json_to_py(py, &settings).map_err(to_pyerr)?,
                ))
            })
            .map_err(blender("building the Blender scene"))?;
        let device = choose_device(py, &settings)?;
        Ok((worker.unbind(), settings.clone(), device))
    })
}

/// Asks Blender for its GPU devices when the engine and `[render] device`
/// need it, picks one ([`device::resolve`]) and switches Cycles to it.
fn choose_device(py: Python<'_>, settings: &serde_json::Value) -> Result<Resolved> {
    let engine: Engine = serde_json::from_value(settings["engine"].clone())
        .map_err(json("the render settings' engine"))?;
    let requested: Device = match settings.get("device") {
        Some(d) => {
            serde_json::from_value(d.clone()).map_err(json("the render settings' device"))?
        }
        None => Device::Auto,
    };
    let render = py.import("blender_scripts.render").map_err(py_err)?;
    let reported: device::Reported = match device::needs_query(engine, requested) {
        false => device::Reported::new(),
        true => {
            let found = render
                .call_method0("cycles_gpu_devices")
                .map_err(blender("asking Blender for its GPU devices"))?;
            let text: String = py
                .import("json")
                .and_then(|json| json.call_method1("dumps", (found,)))
                .and_then(|t| t.extract())
                .map_err(py_err)?;
            serde_json::from_str(&text).map_err(json("Blender's GPU device list"))?
        }
    };
    let chosen = device::resolve(engine, requested, &reported)?;
    if engine == Engine::Cycles {
        render
            .call_method1("use_device", (chosen.used.as_str(),))
            .map_err(blender(format!(
                "switching Cycles to device {}",
                chosen.used
            )))?;
    }
    Ok(chosen)
}

/// The world the render settings name (`studio` when they name none).
fn world_of(settings: &serde_json::Value) -> Result<World> {
    match settings.get(WORLD_KEY) {
        None => Ok(World::Studio),
        Some(w) => serde_json::from_value(w.clone()).map_err(json("the render settings' world")),
    }
}

fn to_pyerr(e: RenderError) -> PyErr {
    pyo3::exceptions::PyValueError::new_err(chain(&e))
}

/// Prepares the sequence, then renders each camera, timing each step (the
/// `part` labels count as part of their camera's time).
fn render(
    worker: &Py<PyAny>,
    settings: &serde_json::Value,
    req: &RenderRequest,
) -> Result<RenderCost> {
    let scale = req.plan.object.axis_scale();
    if !scale.iter().all(|s| s.is_finite() && *s > 0.0) {
        return Err(RenderError::BadPlan {
            id: req.id.clone(),
            reason: format!(
                "plan.object.scale times proportions must be positive on every axis, got {scale:?}"
            ),
        });
    }
    let labeler = match req.parts.is_empty() {
        true => None,
        false => Some(part_labeler(settings, req)?),
    };
    let world = world_of(settings)?;
    let cpu_start = process_cpu_seconds();
    let mut cost = Python::attach(|py| {
        let w = worker.bind(py);
        let start = Instant::now();
        ensure_mesh(py, w, &req.mesh)?;
        let plan = json_to_py(py, &req.plan)?;
        let color = req.object_color.to_vec();
        match world {
            World::Studio => w.call_method1("prepare", (plan.clone(), color)),
            World::Foreign => {
                let range = json_to_py(py, &req.object_color_range)?;
                w.call_method1("prepare", (plan.clone(), color, range))
            }
        }
        .map_err(blender(format!("preparing sequence {}", req.id)))?;
        let mut cost = RenderCost {
            setup_seconds: start.elapsed().as_secs_f64(),
            ..Default::default()
        };
        let head = req
            .head_out_dir
            .as_ref()
            .map(|d| ("head", HEAD_CAMERA_FOLDER, d));
        for (camera, folder, dir) in
            std::iter::once(("wrist", WRIST_CAMERA_FOLDER, &req.out_dir)).chain(head)
        {
            let start = Instant::now();
            let out_dir = dir.to_string_lossy().into_owned();
            w.call_method1(
                "render_camera",
                (plan.clone(), camera, out_dir, req.frame_files.clone()),
            )
            .map_err(blender(format!(
                "rendering sequence {} from the {camera} camera",
                req.id
            )))?;
            if let Some(l) = &labeler {
                label_parts(l, settings, req, camera == "head", dir)
                    .map_err(step(format!("part labels of {} ({camera} camera)", req.id)))?;
            }
            // The plan's sensor (noise, white balance, JPEG) is training's
            // camera; a foreign world's camera model is its own.
            let sensor = match world {
                World::Studio => req.plan.appearance.as_ref().and_then(|a| a.sensor.as_ref()),
                World::Foreign => None,
            };
            if let Some(e) = sensor.filter(|e| e.is_active()) {
                cost.effects_seconds +=
                    super::effects::apply_to_frames(e, camera, dir, &req.frame_files).map_err(
                        step(format!("camera effects of {} ({camera} camera)", req.id)),
                    )?;
            }
            cost.camera_seconds
                .insert(folder.to_string(), start.elapsed().as_secs_f64());
        }
        Ok::<_, RenderError>(cost)
    })?;
    if let (Some(a), Some(b)) = (cpu_start, process_cpu_seconds()) {
        cost.cpu_seconds = b - a;
    }
    Ok(cost)
}

/// User + system CPU seconds of this process, every thread
/// (`/proc/self/stat` fields 14 and 15, in USER_HZ = 100 ticks per second
/// on Linux); None elsewhere.
fn process_cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // The command name (field 2) may hold spaces: count after its ')'.
    let rest = &stat[stat.rfind(')')? + 2..];
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let ticks = |i: usize| fields.get(i)?.parse::<f64>().ok();
    // rest starts at field 3, so fields 14 and 15 are at 11 and 12.
    Some((ticks(11)? + ticks(12)?) / 100.0)
}

fn ensure_mesh(py: Python<'_>, w: &Bound<'_, PyAny>, mesh: &MeshFiles) -> Result<()> {
    let cached: bool = w
        .call_method1("has_mesh", (mesh.object.as_str(),))
        .and_then(|v| v.extract())
        .map_err(py_err)?;
    if cached {
        return Ok(());
    }
    let read = |p: &std::path::Path| {
        std::fs::read(p).map_err(|e| RenderError::io("cannot read mesh file", p, e))
    };
    let (v, f) = (read(&mesh.vertices)?, read(&mesh.faces)?);
    w.call_method1(
        "add_mesh",
        (
            mesh.object.as_str(),
            PyBytes::new(py, &v),
            PyBytes::new(py, &f),
        ),
    )
    .map_err(blender(format!("loading the mesh of '{}'", mesh.object)))?;
    Ok(())
}

fn part_labeler(settings: &serde_json::Value, req: &RenderRequest) -> Result<PartLabeler> {
    let read = |p: &std::path::Path| {
        std::fs::read(p).map_err(|e| RenderError::io("cannot read mesh file", p, e))
    };
    let (v, f) = (read(&req.mesh.vertices)?, read(&req.mesh.faces)?);
    let mesh = TriMesh {
        vertices: v
            .chunks_exact(24)
            .map(|c| {
                std::array::from_fn(|k| {
                    f64::from_le_bytes(c[8 * k..8 * k + 8].try_into().unwrap_or_default())
                })
            })
            .collect(),
        faces: f
            .chunks_exact(12)
            .map(|c| {
                std::array::from_fn(|k| {
                    u32::from_le_bytes(c[4 * k..4 * k + 4].try_into().unwrap_or_default())
                })
            })
            .collect(),
    };
    let bad = mesh
        .faces
        .iter()
        .flatten()
        .any(|&i| i as usize >= mesh.vertices.len());
    if bad {
        return Err(RenderError::Labels(format!(
            "mesh of '{}': a face index is out of range",
            req.mesh.object
        )));
    }
    let tolerance = settings["part_tolerance_m"].as_f64().unwrap_or(0.005);
    PartLabeler::new(&req.parts, &mesh, tolerance)
        .map_err(step(format!("the parts of object '{}'", req.mesh.object)))
}

/// Turns each frame's EXR (depth, object index) into `partNNNNN.png`, and
/// removes the EXR unless the depth or instance pass was asked for too.
fn label_parts(
    labeler: &PartLabeler,
    settings: &serde_json::Value,
    req: &RenderRequest,
    head: bool,
    dir: &std::path::Path,
) -> Result<()> {
    let passes = settings["passes"].as_array().cloned().unwrap_or_default();
    let keep_exr = passes.iter().any(|p| p == "depth" || p == "instance");
    let plan = &req.plan;
    let k = &plan.intrinsics;
    for (frame, name) in plan.frames.iter().zip(&req.frame_files) {
        let pose = match head {
            true => frame
                .head_camera
                .ok_or(RenderError::Protocol("a frame without a head camera pose"))?,
            false => frame.camera,
        };
        let exr = dir.join(name).with_extension("exr");
        let buffers = read_exr(&exr)?;
        let labels = labeler.label(
            &buffers,
            k,
            &pose,
            &plan.object.pose,
            plan.object.axis_scale(),
        )?;
        write_labels(&dir.join(part_file_name(name)), k.width, k.height, labels)?;
        if !keep_exr {
            std::fs::remove_file(&exr).map_err(|e| RenderError::io("cannot remove", &exr, e))?;
        }
    }
    Ok(())
}
