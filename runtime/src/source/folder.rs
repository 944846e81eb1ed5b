//! A recording on disk: a folder of PNG frames, decoded one at a time.

use super::record::read_sequence_json;
use super::{check_fps, Clock, Frame, FrameSource, Pacing, SequenceInfo, SourceError, DEFAULT_FPS};
use grasp_schema::dataset::SEQUENCE_FILE;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// A folder of PNG frames replayed from disk, decoded one at a time.
pub struct SequenceFolder {
    dir: PathBuf,
    files: Vec<PathBuf>,
    info: SequenceInfo,
    clock: Clock,
    next: u64,
}

impl SequenceFolder {
    /// Opens `dir`. The frame rate is `fps` if given, else `plan.fps` from
    /// `sequence.json`, else [`DEFAULT_FPS`].
    pub fn open(dir: &Path, fps: Option<f64>, pacing: Pacing) -> Result<Self, SourceError> {
        let dir_buf = || dir.to_path_buf();
        if !dir.is_dir() {
            return Err(SourceError::NotADirectory { dir: dir_buf() });
        }
        let record = dir.join(SEQUENCE_FILE);
        let (files, info) = if record.exists() {
            read_sequence_json(&record)?
        } else {
            (list_pngs(dir)?, SequenceInfo::default())
        };
        if files.is_empty() {
            return Err(SourceError::NoFrames { dir: dir_buf() });
        }
        let files: Vec<PathBuf> = files.into_iter().map(|f| dir.join(f)).collect();
        if let Some(missing) = files.iter().find(|f| !f.is_file()) {
            return Err(SourceError::MissingFrame {
                frame: missing.clone(),
                record,
            });
        }
        let fps = fps.or(info.fps).unwrap_or(DEFAULT_FPS);
        check_fps(fps).map_err(|source| SourceError::FrameRate {
            dir: dir_buf(),
            source,
        })?;
        Ok(SequenceFolder {
            dir: dir.to_path_buf(),
            files,
            info,
            clock: Clock {
                fps,
                pacing,
                start: Instant::now(),
            },
            next: 0,
        })
    }

    pub fn info(&self) -> &SequenceInfo {
        &self.info
    }

    /// Width and height of the recording's first frame (read from its
    /// header only).
    pub fn frame_size(&self) -> Result<(u32, u32), SourceError> {
        let first = &self.files[0];
        image::image_dimensions(first).map_err(|source| SourceError::FrameSize {
            frame: first.clone(),
            source,
        })
    }

    pub fn fps(&self) -> f64 {
        self.clock.fps
    }

    pub fn len(&self) -> usize {
        self.files.len()
    }

    pub fn is_empty(&self) -> bool {
        self.files.is_empty()
    }
}

impl FrameSource for SequenceFolder {
    fn begin(&mut self) -> Result<(), SourceError> {
        self.next = 0;
        self.clock.start = Instant::now();
        Ok(())
    }

    fn next_frame(&mut self) -> Result<Option<Frame>, SourceError> {
        let Some(path) = self.files.get(self.next as usize) else {
            return Ok(None);
        };
        let index = self.next;
        self.clock.wait_for(index);
        let image = image::open(path)
            .map_err(|source| SourceError::Decode {
                frame: path.clone(),
                source,
            })?
            .to_rgb8();
        self.next += 1;
        Ok(Some(Frame {
            index,
            time_s: self.clock.time_of(index),
            image,
        }))
    }

    fn describe(&self) -> String {
        format!(
            "{} ({} frames at {} fps)",
            self.dir.display(),
            self.files.len(),
            self.clock.fps
        )
    }
}

fn list_pngs(dir: &Path) -> Result<Vec<PathBuf>, SourceError> {
    let cannot_list = |source| SourceError::List {
        dir: dir.to_path_buf(),
        source,
    };
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(cannot_list)? {
        let path = entry.map_err(cannot_list)?.path();
        let is_png = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("png"));
        if is_png && path.is_file() {
            files.push(PathBuf::from(
                path.file_name().expect("listed file has a name"),
            ));
        }
    }
    // Zero-padded names sort in frame order.
    files.sort();
    Ok(files)
}
