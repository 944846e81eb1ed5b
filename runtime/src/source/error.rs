//! Why frames cannot be had.

use grasp_model::input::InputError;
use std::io;
use std::path::PathBuf;

/// Why frames cannot be had: every variant names the folder, file or
/// device.
#[derive(Debug, thiserror::Error)]
pub enum SourceError {
    #[error("{} is not a directory", dir.display())]
    NotADirectory { dir: PathBuf },
    #[error("cannot list {}", dir.display())]
    List {
        dir: PathBuf,
        #[source]
        source: io::Error,
    },
    #[error("{} holds no PNG frames", dir.display())]
    NoFrames { dir: PathBuf },
    #[error("frame {} listed in {} is missing", frame.display(), record.display())]
    MissingFrame { frame: PathBuf, record: PathBuf },
    #[error("cannot read {}", path.display())]
    Read {
        path: PathBuf,
        #[source]
        source: io::Error,
    },
    #[error("{} is not valid JSON", path.display())]
    Json {
        path: PathBuf,
        #[source]
        source: serde_json::Error,
    },
    /// A field of `sequence.json` the runtime needs is missing or wrong.
    #[error("{}: `{field}` {problem}", path.display())]
    Field {
        path: PathBuf,
        field: String,
        problem: &'static str,
    },
    #[error("frame rate of {}", dir.display())]
    FrameRate {
        dir: PathBuf,
        #[source]
        source: BadFrameRate,
    },
    /// `plan.intrinsics` is there but does not parse.
    #[error("{}: plan.intrinsics: {reason}", path.display())]
    Intrinsics { path: PathBuf, reason: String },
    /// `plan.intrinsics` parses but is not a usable lens.
    #[error("{}: {reason}", path.display())]
    Lens { path: PathBuf, reason: InputError },
    /// The model looks further out than the recording was rendered.
    #[error("{}: {reason}", dir.display())]
    CropOutside { dir: PathBuf, reason: String },
    #[error("cannot read the size of frame {}", frame.display())]
    FrameSize {
        frame: PathBuf,
        #[source]
        source: image::ImageError,
    },
    #[error("cannot decode frame {}", frame.display())]
    Decode {
        frame: PathBuf,
        #[source]
        source: image::ImageError,
    },
    #[error("cannot open camera {}", device.display())]
    OpenCamera {
        device: PathBuf,
        #[source]
        source: io::Error,
    },
    /// The camera offers no pixel format the runtime decodes.
    #[error("{}: supports neither YUYV nor MJPG (it offers {offered})", device.display())]
    CameraFormat { device: PathBuf, offered: String },
    /// A camera refused a setting or a step (`doing` says which).
    #[error("{}: {doing}", device.display())]
    Camera {
        device: PathBuf,
        doing: String,
        #[source]
        source: io::Error,
    },
    /// A live source lost its device, or delivered a frame that does not
    /// decode.
    #[error("{}: capture failed", device.display())]
    Capture {
        device: PathBuf,
        #[source]
        source: io::Error,
    },
    #[error("cannot start the frame feed thread")]
    FeedThread(#[source] io::Error),
}

/// A frame rate outside (0, 1000] frames/s.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error("frame rate must be in (0, 1000] fps, got {fps}")]
pub struct BadFrameRate {
    pub fps: f64,
}
