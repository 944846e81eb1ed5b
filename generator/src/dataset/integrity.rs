//! Integrity checks of the files a sequence folder holds, without decoding
//! pixels: a PNG's chunk structure and CRCs up to its `IEND`, an EXR's
//! headers, offset tables and every (still compressed) chunk. A file cut
//! short by a full disk or a killed writer fails them; so does a flipped
//! byte in a PNG. The full decode (`--decode`) is kept for the paranoid.

use std::fmt;
use std::io::{BufReader, Read};
use std::path::Path;

const PNG_SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n'];
/// The PNG specification's bound on a chunk's length.
const MAX_CHUNK_LEN: u32 = (1 << 31) - 1;

/// Why a file failed its check (the path is added by the caller).
#[derive(Debug, Clone, PartialEq)]
pub struct Damage(pub String);

impl fmt::Display for Damage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Damage {}

fn damage(msg: impl Into<String>) -> Damage {
    Damage(msg.into())
}

/// Image files a sequence folder holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImageKind {
    Png,
    Exr,
}

impl ImageKind {
    pub fn of(path: &Path) -> Option<ImageKind> {
        match path.extension()?.to_str()? {
            "png" => Some(ImageKind::Png),
            "exr" => Some(ImageKind::Exr),
            _ => None,
        }
    }
}

/// Checks an image file and returns its size (width, height). `decode`
/// decodes every pixel too (slower; catches damage inside compressed data
/// that the container's checks cannot see, e.g. in an EXR chunk).
pub fn check_image(path: &Path, decode: bool) -> Result<(u32, u32), Damage> {
    let kind = ImageKind::of(path).ok_or_else(|| damage("not a .png or .exr file"))?;
    let bytes = std::fs::read(path).map_err(|e| damage(io_reason(&e)))?;
    match kind {
        ImageKind::Png => {
            let size = check_png(&bytes)?;
            if decode {
                image::load_from_memory_with_format(&bytes, image::ImageFormat::Png)
                    .map_err(|e| damage(format!("cannot decode: {e}")))?;
            }
            Ok(size)
        }
        ImageKind::Exr => {
            let size = check_exr(&bytes)?;
            if decode {
                exr::prelude::read_all_flat_layers_from_file(path)
                    .map_err(|e| damage(format!("cannot decode: {e}")))?;
            }
            Ok(size)
        }
    }
}

fn io_reason(e: &std::io::Error) -> String {
    match e.kind() {
        std::io::ErrorKind::NotFound => "missing".to_string(),
        _ => format!("cannot read: {e}"),
    }
}

/// Walks a PNG's chunks: the signature, `IHDR` first, every chunk's CRC,
/// at least one `IDAT`, and `IEND` last with nothing after it. Returns the
/// size from `IHDR`.
pub fn check_png(bytes: &[u8]) -> Result<(u32, u32), Damage> {
    if bytes.is_empty() {
        return Err(damage("empty file"));
    }
    if bytes.len() < PNG_SIGNATURE.len() || bytes[..8] != PNG_SIGNATURE {
        return Err(damage("not a PNG (bad signature)"));
    }
    let mut pos = PNG_SIGNATURE.len();
    let mut size = None;
    let mut idat = false;
    loop {
        let Some(header) = bytes.get(pos..pos + 8) else {
            return Err(damage(format!(
                "truncated: ends at byte {} before the IEND chunk",
                bytes.len()
            )));
        };
        let len = u32::from_be_bytes([header[0], header[1], header[2], header[3]]);
        let kind = [header[4], header[5], header[6], header[7]];
        let name = String::from_utf8_lossy(&kind).into_owned();
        if len > MAX_CHUNK_LEN || !kind.iter().all(u8::is_ascii_alphabetic) {
            return Err(damage(format!("corrupt chunk header at byte {pos}")));
        }
        let end = pos + 8 + len as usize + 4;
        if end > bytes.len() {
            return Err(damage(format!(
                "truncated: chunk {name} at byte {pos} needs {} bytes, the file has {}",
                end,
                bytes.len()
            )));
        }
        let data = &bytes[pos + 8..end - 4];
        let stored = u32::from_be_bytes([
            bytes[end - 4],
            bytes[end - 3],
            bytes[end - 2],
            bytes[end - 1],
        ]);
        let mut crc = crc32fast::Hasher::new();
        crc.update(&kind);
        crc.update(data);
        if crc.finalize() != stored {
            return Err(damage(format!("chunk {name} at byte {pos}: CRC mismatch")));
        }
        match (&kind, size) {
            (b"IHDR", None) if len == 13 => {
                let w = u32::from_be_bytes([data[0], data[1], data[2], data[3]]);
                let h = u32::from_be_bytes([data[4], data[5], data[6], data[7]]);
                size = Some((w, h));
            }
            (_, None) => return Err(damage("the first chunk is not a valid IHDR")),
            (b"IDAT", _) => idat = true,
            (b"IEND", Some(s)) => {
                if !idat {
                    return Err(damage("no IDAT chunk (no pixel data)"));
                }
                if end != bytes.len() {
                    return Err(damage(format!(
                        "{} unexpected bytes after IEND",
                        bytes.len() - end
                    )));
                }
                return Ok(s);
            }
            _ => {}
        }
        pos = end;
    }
}

/// Reads an EXR's headers and offset tables (validated against the file's
/// length) and every chunk, without decompressing them; nothing may follow
/// the last chunk. Returns the data window's size of the first part.
pub fn check_exr(bytes: &[u8]) -> Result<(u32, u32), Damage> {
    if bytes.is_empty() {
        return Err(damage("empty file"));
    }
    let read = BufReader::new(std::io::Cursor::new(bytes));
    let reader = exr::block::reader::Reader::read_from_buffered(read, true)
        .map_err(|e| damage(format!("bad EXR header: {e}")))?;
    let size = reader
        .headers()
        .first()
        .map(|h| h.layer_size)
        .ok_or_else(|| damage("EXR without a part"))?;
    let chunks = reader
        .all_chunks(true)
        .map_err(|e| damage(format!("bad EXR offset table (truncated?): {e}")))?;
    for (i, chunk) in chunks.enumerate() {
        chunk.map_err(|e| damage(format!("EXR chunk {i} unreadable (truncated?): {e}")))?;
    }
    Ok((size.width() as u32, size.height() as u32))
}

/// Whether `bytes` parse as JSON (a `sequence.json` cut short does not).
pub fn check_json(path: &Path) -> Result<(), Damage> {
    let mut text = String::new();
    std::fs::File::open(path)
        .and_then(|mut f| f.read_to_string(&mut text))
        .map_err(|e| damage(io_reason(&e)))?;
    serde_json::from_str::<serde_json::Value>(&text)
        .map(|_| ())
        .map_err(|e| damage(format!("invalid JSON: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn png(w: u32, h: u32) -> Vec<u8> {
        let img = image::RgbImage::from_fn(w, h, |x, y| image::Rgb([x as u8, y as u8, 7]));
        let mut out = std::io::Cursor::new(Vec::new());
        img.write_to(&mut out, image::ImageFormat::Png).unwrap();
        out.into_inner()
    }

    #[test]
    fn a_whole_png_passes_with_its_size() {
        assert_eq!(check_png(&png(5, 3)), Ok((5, 3)));
    }

    #[test]
    fn every_truncation_of_a_png_is_caught() {
        let bytes = png(16, 16);
        for cut in 0..bytes.len() {
            assert!(check_png(&bytes[..cut]).is_err(), "cut at {cut} passed");
        }
    }

    #[test]
    fn a_flipped_byte_or_trailing_bytes_are_caught() {
        let bytes = png(16, 16);
        for i in 8..bytes.len() {
            let mut b = bytes.clone();
            b[i] ^= 0x10;
            assert!(check_png(&b).is_err(), "flip at {i} passed");
        }
        let mut b = bytes.clone();
        b.extend_from_slice(b"junk");
        assert!(check_png(&b).unwrap_err().0.contains("after IEND"));
    }

    fn exr(w: usize, h: usize) -> Vec<u8> {
        use exr::prelude::*;
        let channels =
            SpecificChannels::rgba(|p: Vec2<usize>| (p.x() as f32, p.y() as f32, 0.5_f32, 1.0_f32));
        let image = Image::from_channels((w, h), channels);
        let mut out = std::io::Cursor::new(Vec::new());
        image.write().to_buffered(&mut out).unwrap();
        out.into_inner()
    }

    #[test]
    fn a_whole_exr_passes_and_truncations_fail() {
        let bytes = exr(7, 40);
        assert_eq!(check_exr(&bytes), Ok((7, 40)));
        for cut in (0..bytes.len()).step_by(7) {
            assert!(check_exr(&bytes[..cut]).is_err(), "cut at {cut} passed");
        }
        let mut b = bytes.clone();
        b.push(0);
        assert!(check_exr(&b).is_err(), "a trailing byte passed");
    }
}
