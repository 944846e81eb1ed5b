//! Live UVC/V4L2 capture (feature `camera`), through the pure-Rust
//! `linuxvideo` crate: no libv4l or other system library is needed.
//! YUYV is preferred (no decoding cost); MJPG is decoded with `image`.

use crate::source::{Frame, FrameSource, SourceError};
use image::RgbImage;
use linuxvideo::format::{PixFormat, PixelFormat};
use linuxvideo::stream::ReadStream;
use linuxvideo::{BufType, Device, Fract};
use std::path::{Path, PathBuf};
use std::time::Instant;

pub struct Camera {
    path: PathBuf,
    stream: ReadStream,
    decode: Decode,
    start: Instant,
    next: u64,
}

impl Camera {
    /// Opens `path` (e.g. `/dev/video0`) asking for `width` x `height` at
    /// `fps`; the driver may pick the nearest mode it supports.
    pub fn open(path: &Path, width: u32, height: u32, fps: u32) -> Result<Camera, SourceError> {
        let device = Device::open(path).map_err(|source| SourceError::OpenCamera {
            device: path.to_path_buf(),
            source,
        })?;
        let formats = device
            .formats(BufType::VIDEO_CAPTURE)
            .map(|f| f.map(|f| f.pixel_format()))
            .collect::<std::io::Result<Vec<_>>>()
            .map_err(failed(path, "cannot list pixel formats"))?;
        let Some(format) = [PixelFormat::YUYV, PixelFormat::MJPG]
            .into_iter()
            .find(|f| formats.contains(f))
        else {
            return Err(SourceError::CameraFormat {
                device: path.to_path_buf(),
                offered: format!("{formats:?}"),
            });
        };
        let capture = device
            .video_capture(PixFormat::new(width, height, format))
            .map_err(failed(
                path,
                format!("cannot set {width}x{height} {format:?}"),
            ))?;
        if let Err(e) = capture.set_frame_interval(Fract::new(1, fps.max(1))) {
            tracing::warn!(
                "{}: cannot set {fps} fps ({e}); using the driver's rate",
                path.display()
            );
        }
        let negotiated = capture.format();
        let (width, height) = (negotiated.width(), negotiated.height());
        let bytes_per_line = negotiated.bytes_per_line();
        let format = negotiated.pixel_format();
        let stream = capture
            .into_stream()
            .map_err(failed(path, "cannot start streaming"))?;
        tracing::info!("{}: {width}x{height} {format:?}", path.display());
        Ok(Camera {
            path: path.to_path_buf(),
            stream,
            decode: Decode {
                format,
                width,
                height,
                bytes_per_line,
            },
            start: Instant::now(),
            next: 0,
        })
    }
}

impl FrameSource for Camera {
    fn begin(&mut self) -> Result<(), SourceError> {
        // Frames queued by the driver before the trigger are stale.
        let stale = failed(
            &self.path,
            "cannot drop the frames queued before the trigger",
        );
        while !self.stream.will_block().map_err(&stale)? {
            self.stream.dequeue(|_| Ok(())).map_err(&stale)?;
        }
        self.start = Instant::now();
        self.next = 0;
        Ok(())
    }

    fn next_frame(&mut self) -> Result<Option<Frame>, SourceError> {
        let decode = &self.decode;
        let image = self
            .stream
            .dequeue(|buf| decode.convert(&buf))
            .map_err(|source| SourceError::Capture {
                device: self.path.clone(),
                source,
            })?;
        let index = self.next;
        self.next += 1;
        Ok(Some(Frame {
            index,
            time_s: self.start.elapsed().as_secs_f64(),
            image,
        }))
    }

    fn describe(&self) -> String {
        format!(
            "camera {} ({}x{} {:?})",
            self.path.display(),
            self.decode.width,
            self.decode.height,
            self.decode.format
        )
    }
}

/// The error of a camera step that failed (`doing`: what it tried).
fn failed(device: &Path, doing: impl Into<String>) -> impl Fn(std::io::Error) -> SourceError {
    let (device, doing) = (device.to_path_buf(), doing.into());
    move |source| SourceError::Camera {
        device: device.clone(),
        doing: doing.clone(),
        source,
    }
}

/// Turns one driver buffer into an RGB image.
struct Decode {
    format: PixelFormat,
    width: u32,
    height: u32,
    bytes_per_line: u32,
}

impl Decode {
    fn convert(&self, data: &[u8]) -> std::io::Result<RgbImage> {
        let bad = |m: String| std::io::Error::new(std::io::ErrorKind::InvalidData, m);
        if self.format == PixelFormat::MJPG {
            return image::load_from_memory_with_format(data, image::ImageFormat::Jpeg)
                .map(|i| i.to_rgb8())
                .map_err(|e| bad(format!("bad MJPG frame: {e}")));
        }
        let stride = self.bytes_per_line as usize;
        if data.len() < stride * self.height as usize || stride < self.width as usize * 2 {
            return Err(bad(format!("short YUYV frame ({} bytes)", data.len())));
        }
        Ok(yuyv_to_rgb(data, self.width, self.height, stride))
    }
}

/// YUYV 4:2:2 (BT.601, limited range) to RGB.
pub fn yuyv_to_rgb(data: &[u8], width: u32, height: u32, stride: usize) -> RgbImage {
    let mut out = RgbImage::new(width, height);
    for y in 0..height {
        let row = &data[y as usize * stride..];
        for x in 0..width {
            let pair = (x as usize / 2) * 4;
            let luma = row[pair + if x % 2 == 0 { 0 } else { 2 }];
            let (u, v) = (row[pair + 1], row[pair + 3]);
            out.put_pixel(x, y, image::Rgb(ycbcr_to_rgb(luma, u, v)));
        }
    }
    out
}

fn ycbcr_to_rgb(y: u8, u: u8, v: u8) -> [u8; 3] {
    let c = 1.164 * (f32::from(y) - 16.0);
    let d = f32::from(u) - 128.0;
    let e = f32::from(v) - 128.0;
    let clamp = |x: f32| x.round().clamp(0.0, 255.0) as u8;
    [
        clamp(c + 1.596 * e),
        clamp(c - 0.392 * d - 0.813 * e),
        clamp(c + 2.017 * d),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn yuyv_grey_and_primaries_convert() {
        // Two pixels sharing chroma: black-ish and white-ish grey.
        let img = yuyv_to_rgb(&[16, 128, 235, 128], 2, 1, 4);
        assert_eq!(img.get_pixel(0, 0).0, [0, 0, 0]);
        assert_eq!(img.get_pixel(1, 0).0, [255, 255, 255]);
        // BT.601 red: Y 81, U 90, V 240.
        let red = yuyv_to_rgb(&[81, 90, 81, 240], 2, 1, 4);
        let [r, g, b] = red.get_pixel(0, 0).0;
        assert!(r > 250 && g < 5 && b < 5, "{r} {g} {b}");
    }
}
