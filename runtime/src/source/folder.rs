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

#[cfg(test)]
mod tests {
    use super::*;
    use grasp_model::input::Lens;
    use grasp_schema::taxonomy::{Class, Preshape};
    use image::RgbImage;

    fn write_frames(dir: &Path, n: usize) {
        for i in 0..n {
            let img = RgbImage::from_pixel(4, 3, image::Rgb([i as u8, 0, 0]));
            img.save(dir.join(format!("{i:05}.png"))).unwrap();
        }
    }

    #[test]
    fn bare_pngs_replay_in_name_order_at_the_default_rate() {
        let dir = tempfile::tempdir().unwrap();
        write_frames(dir.path(), 3);
        std::fs::write(dir.path().join("notes.txt"), "x").unwrap();
        let mut s = SequenceFolder::open(dir.path(), None, Pacing::AsFastAsPossible).unwrap();
        s.begin().unwrap();
        let mut got = Vec::new();
        while let Some(f) = s.next_frame().unwrap() {
            got.push((f.index, f.image.get_pixel(0, 0)[0], f.time_s));
        }
        assert_eq!(
            got,
            vec![(0, 0, 0.0), (1, 1, 1.0 / 30.0), (2, 2, 2.0 / 30.0)]
        );
    }

    #[test]
    fn sequence_json_gives_the_frame_rate_order_and_labels() {
        let dir = tempfile::tempdir().unwrap();
        write_frames(dir.path(), 2);
        let record = serde_json::json!({
            "plan": {"fps": 10.0, "preshape": "pinch3",
                     "frames": [{"class": "pinch3"}, {"class": "no_grasp"}]},
            "frame_files": ["00001.png", "00000.png"],
        });
        std::fs::write(dir.path().join(SEQUENCE_FILE), record.to_string()).unwrap();
        let mut s = SequenceFolder::open(dir.path(), None, Pacing::AsFastAsPossible).unwrap();
        assert_eq!(s.fps(), 10.0);
        assert_eq!(s.info().preshape, Some(Preshape::Pinch3));
        assert_eq!(s.info().labels, vec![Class::Pinch3, Class::NoGrasp]);
        s.begin().unwrap();
        let f = s.next_frame().unwrap().unwrap();
        assert_eq!(f.image.get_pixel(0, 0)[0], 1);
    }

    #[test]
    fn the_recordings_focal_length_is_read_along_its_shorter_side() {
        let dir = tempfile::tempdir().unwrap();
        write_frames(dir.path(), 1);
        let record = |intrinsics: serde_json::Value| {
            let r = serde_json::json!({
                "plan": {"fps": 10.0, "intrinsics": intrinsics}, "frame_files": ["00000.png"],
            });
            std::fs::write(dir.path().join(SEQUENCE_FILE), r.to_string()).unwrap();
            let s = SequenceFolder::open(dir.path(), None, Pacing::AsFastAsPossible).unwrap();
            s.info().lens().map_err(|e| e.to_string())
        };
        let lens =
            |w: u32, h: u32| serde_json::json!({"width": w, "height": h, "fx": 300.0, "fy": 200.0});
        let focal = |f: f64, width: u32, height: u32| {
            Ok(Some(Lens::Focal {
                focal_px: f,
                width,
                height,
            }))
        };
        assert_eq!(record(lens(640, 480)), focal(200.0, 640, 480));
        assert_eq!(record(lens(480, 640)), focal(300.0, 480, 640));
        // A focal length of 0 (or negative) names its field, instead of
        // reading as "no plan.intrinsics".
        for bad in [0.0, -1.0] {
            let err = record(serde_json::json!({"width": 64, "height": 64, "fx": bad, "fy": bad}))
                .unwrap_err();
            assert!(err.contains("plan.intrinsics.fy"), "{err}");
        }
        let err = record(serde_json::json!({"width": 64, "height": 64})).unwrap_err();
        assert!(
            err.contains("plan.intrinsics") && err.contains("fx"),
            "{err}"
        );
        assert_eq!(
            SequenceFolder::open(dir.path(), None, Pacing::AsFastAsPossible)
                .unwrap()
                .frame_size()
                .unwrap(),
            (4, 3)
        );
    }

    #[test]
    fn a_centre_only_recording_refuses_a_model_that_looks_wider() {
        let dir = tempfile::tempdir().unwrap();
        write_frames(dir.path(), 1);
        let record = |region: serde_json::Value| {
            let r = serde_json::json!({
                "plan": {"fps": 10.0}, "frame_files": ["00000.png"],
                "render": {"center_region": region},
            });
            std::fs::write(dir.path().join(SEQUENCE_FILE), r.to_string()).unwrap();
        };
        record(serde_json::json!(0.5));
        let s = SequenceFolder::open(dir.path(), None, Pacing::AsFastAsPossible).unwrap();
        assert_eq!(s.info().center_region, Some(0.5));
        s.info().check_crop(Some(0.42), dir.path()).unwrap();
        for crop in [Some(0.6), None] {
            let err = s.info().check_crop(crop, dir.path()).unwrap_err();
            assert!(
                err.to_string()
                    .contains("rendered only in their central 0.5"),
                "{err}"
            );
        }
        record(serde_json::json!("half"));
        let err = SequenceFolder::open(dir.path(), None, Pacing::AsFastAsPossible)
            .err()
            .unwrap();
        assert!(err.to_string().contains("render.center_region"), "{err}");
    }

    #[test]
    fn bad_inputs_name_the_file_and_field() {
        let dir = tempfile::tempdir().unwrap();
        let err = SequenceFolder::open(dir.path(), None, Pacing::RealTime)
            .err()
            .unwrap();
        assert!(err.to_string().contains("no PNG frames"));
        std::fs::write(dir.path().join(SEQUENCE_FILE), r#"{"frame_files": 3}"#).unwrap();
        let err = SequenceFolder::open(dir.path(), None, Pacing::RealTime)
            .err()
            .unwrap();
        assert!(err.to_string().contains("frame_files"), "{err}");
        std::fs::write(
            dir.path().join(SEQUENCE_FILE),
            r#"{"frame_files": ["00000.png"], "plan": {"fps": 0}}"#,
        )
        .unwrap();
        let err = SequenceFolder::open(dir.path(), None, Pacing::RealTime)
            .err()
            .unwrap();
        assert!(err.to_string().contains("missing"), "{err}");
        write_frames(dir.path(), 1);
        let err = SequenceFolder::open(dir.path(), None, Pacing::RealTime)
            .err()
            .unwrap();
        assert!(format!("{err:#}").contains("frame rate"), "{err:#}");
        std::fs::write(dir.path().join("00000.png"), b"not a png").unwrap();
        let mut s = SequenceFolder::open(dir.path(), Some(30.0), Pacing::RealTime).unwrap();
        s.begin().unwrap();
        let err = s.next_frame().unwrap_err();
        assert!(format!("{err:#}").contains("00000.png"), "{err:#}");
    }
}
