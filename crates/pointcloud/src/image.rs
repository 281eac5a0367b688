//! Small image toolkit for the files this crate writes: an RGB raster with line, rectangle and
//! text drawing (a built-in 5×7 font), PNG output, and float32 depth TIFF output and input.
//!
//! ```
//! use lgdm_pointcloud::image::RgbImage;
//! let mut img = RgbImage::new(64, 32, [0, 0, 0]);
//! img.draw_line([2.0, 2.0], [60.0, 30.0], [255, 0, 0], 1);
//! img.draw_text(2, 20, "mug_01", [255, 255, 255], 1);
//! assert_eq!(img.get(2, 2), [255, 0, 0]);
//! ```

use std::fs::File;
use std::path::{Path, PathBuf};

use lgdm_base::fs::write_atomic;

/// Errors writing or reading images.
#[derive(Debug, thiserror::Error)]
#[error("image {}: {reason}", path.display())]
pub struct ImageError {
    /// The file.
    pub path: PathBuf,
    /// What went wrong.
    pub reason: String,
}

fn err(path: &Path, reason: impl std::fmt::Display) -> ImageError {
    ImageError {
        path: path.to_path_buf(),
        reason: reason.to_string(),
    }
}

/// An 8-bit RGB image, row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct RgbImage {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Pixels, row-major.
    pub data: Vec<[u8; 3]>,
}

impl RgbImage {
    /// A `width × height` image filled with `fill`.
    pub fn new(width: usize, height: usize, fill: [u8; 3]) -> Self {
        Self {
            width,
            height,
            data: vec![fill; width * height],
        }
    }

    /// An image from row-major pixels (`data.len() == width × height`).
    pub fn from_pixels(width: usize, height: usize, data: Vec<[u8; 3]>) -> Self {
        assert_eq!(
            data.len(),
            width * height,
            "pixel count must be width × height"
        );
        Self {
            width,
            height,
            data,
        }
    }

    /// The pixel at `(x, y)`.
    pub fn get(&self, x: usize, y: usize) -> [u8; 3] {
        self.data[y * self.width + x]
    }

    /// Sets a pixel; coordinates outside the image are ignored.
    pub fn put(&mut self, x: i64, y: i64, c: [u8; 3]) {
        if x >= 0 && y >= 0 && (x as usize) < self.width && (y as usize) < self.height {
            self.data[y as usize * self.width + x as usize] = c;
        }
    }

    /// Draws a line of `thickness` pixels from `a` to `b` (pixel coordinates).
    pub fn draw_line(&mut self, a: [f32; 2], b: [f32; 2], c: [u8; 3], thickness: usize) {
        let steps = ((b[0] - a[0]).abs().max((b[1] - a[1]).abs()).ceil() as usize).max(1);
        let r = thickness.saturating_sub(1) as i64 / 2;
        let extra = thickness.saturating_sub(1) as i64 % 2;
        for s in 0..=steps {
            let t = s as f32 / steps as f32;
            let x = (a[0] + (b[0] - a[0]) * t).round() as i64;
            let y = (a[1] + (b[1] - a[1]) * t).round() as i64;
            for dy in -r..=r + extra {
                for dx in -r..=r + extra {
                    self.put(x + dx, y + dy, c);
                }
            }
        }
    }

    /// Copies `src` with its top-left corner at `(x, y)` (clipped).
    pub fn blit(&mut self, src: &RgbImage, x: i64, y: i64) {
        for sy in 0..src.height {
            for sx in 0..src.width {
                self.put(x + sx as i64, y + sy as i64, src.get(sx, sy));
            }
        }
    }

    /// Draws `text` (upper-cased, 5×7 glyphs, `scale` pixels per glyph pixel) with its top-left
    /// corner at `(x, y)`. Characters without a glyph are drawn as spaces.
    pub fn draw_text(&mut self, x: i64, y: i64, text: &str, c: [u8; 3], scale: usize) {
        let scale = scale.max(1) as i64;
        for (i, ch) in text.chars().enumerate() {
            let rows = glyph(ch.to_ascii_uppercase());
            let ox = x + i as i64 * 6 * scale;
            for (ry, bits) in rows.iter().enumerate() {
                for rx in 0..5 {
                    if bits & (0x10 >> rx) != 0 {
                        for sy in 0..scale {
                            for sx in 0..scale {
                                self.put(ox + rx * scale + sx, y + ry as i64 * scale + sy, c);
                            }
                        }
                    }
                }
            }
        }
    }

    /// The sub-image `[x, x + w) × [y, y + h)`, clipped to the image (pixels outside are black).
    pub fn crop(&self, x: i64, y: i64, w: usize, h: usize) -> RgbImage {
        let mut out = RgbImage::new(w, h, [0, 0, 0]);
        for oy in 0..h {
            for ox in 0..w {
                let (sx, sy) = (x + ox as i64, y + oy as i64);
                if sx >= 0 && sy >= 0 && (sx as usize) < self.width && (sy as usize) < self.height {
                    out.data[oy * w + ox] = self.get(sx as usize, sy as usize);
                }
            }
        }
        out
    }

    /// Nearest-neighbour upscaling by an integer factor.
    pub fn upscale(&self, factor: usize) -> RgbImage {
        let f = factor.max(1);
        let mut out = RgbImage::new(self.width * f, self.height * f, [0, 0, 0]);
        for y in 0..out.height {
            for x in 0..out.width {
                out.data[y * out.width + x] = self.get(x / f, y / f);
            }
        }
        out
    }

    /// Width in pixels of `text` drawn at `scale`.
    pub fn text_width(text: &str, scale: usize) -> usize {
        text.chars().count() * 6 * scale.max(1)
    }

    /// Writes the image as an 8-bit RGB PNG (atomically: temp file, then rename).
    pub fn write_png(&self, path: &Path) -> Result<(), ImageError> {
        write_atomic(path, |file| self.encode_png_to(file)).map_err(|e| err(path, e))
    }

    /// The image as the bytes of an 8-bit RGB PNG file (the bytes [`RgbImage::write_png`]
    /// writes); an error for an empty image.
    pub fn encode_png(&self) -> std::io::Result<Vec<u8>> {
        let mut out = Vec::new();
        self.encode_png_to(&mut out)?;
        Ok(out)
    }

    fn encode_png_to(&self, out: &mut impl std::io::Write) -> std::io::Result<()> {
        let bytes: Vec<u8> = self.data.iter().flatten().copied().collect();
        let mut enc = png::Encoder::new(out, self.width as u32, self.height as u32);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header().map_err(std::io::Error::other)?;
        w.write_image_data(&bytes).map_err(std::io::Error::other)?;
        w.finish().map_err(std::io::Error::other)
    }

    /// Reads an 8-bit RGB or RGBA PNG (alpha dropped). A header declaring more pixels than
    /// the file's compressed data can hold is an error, before anything is allocated.
    pub fn read_png(path: &Path) -> Result<RgbImage, ImageError> {
        let file = File::open(path).map_err(|e| err(path, e))?;
        let file_len = file.metadata().map_err(|e| err(path, e))?.len();
        let decoder = png::Decoder::new(std::io::BufReader::new(file));
        let mut reader = decoder.read_info().map_err(|e| err(path, e))?;
        let size = reader
            .output_buffer_size()
            .ok_or_else(|| err(path, "image too large"))?;
        // Deflate expands at most 1032:1, so the pixels of a PNG take at most ~1032 bytes per
        // byte of file; a header claiming more is corrupt (and would make us allocate it).
        let most = usize::try_from(file_len)
            .unwrap_or(usize::MAX)
            .saturating_mul(DEFLATE_MAX_RATIO)
            .saturating_add(1 << 16);
        if size > most {
            let (w, h) = reader.info().size();
            return Err(err(
                path,
                format!(
                    "the header declares a {w}×{h} image ({size} bytes), more than a \
                     {file_len}-byte PNG can hold"
                ),
            ));
        }
        let mut buf = vec![0; size];
        let info = reader.next_frame(&mut buf).map_err(|e| err(path, e))?;
        let channels = match (info.color_type, info.bit_depth) {
            (png::ColorType::Rgb, png::BitDepth::Eight) => 3,
            (png::ColorType::Rgba, png::BitDepth::Eight) => 4,
            other => return Err(err(path, format!("unsupported PNG colour type {other:?}"))),
        };
        let data = buf[..info.buffer_size()]
            .chunks_exact(channels)
            .map(|p| [p[0], p[1], p[2]])
            .collect();
        Ok(RgbImage::from_pixels(
            info.width as usize,
            info.height as usize,
            data,
        ))
    }
}

/// The largest expansion of deflate (zlib) data, 1032:1: bounds what a compressed image file
/// can decode to.
pub const DEFLATE_MAX_RATIO: usize = 1032;

/// Writes a single-channel float32 TIFF (depth in metres, uncompressed).
pub fn write_depth_tiff(
    path: &Path,
    width: usize,
    height: usize,
    depth_m: &[f32],
) -> Result<(), ImageError> {
    if depth_m.len() != width * height {
        return Err(err(path, "depth length is not width × height"));
    }
    write_atomic(path, |file| {
        let mut enc = tiff::encoder::TiffEncoder::new(file).map_err(std::io::Error::other)?;
        enc.write_image::<tiff::encoder::colortype::Gray32Float>(
            width as u32,
            height as u32,
            depth_m,
        )
        .map_err(std::io::Error::other)
    })
    .map_err(|e| err(path, e))
}

/// Reads a single-channel float32 TIFF; returns `(width, height, values)`. The decoder's buffers
/// are limited by the file's size (at most [`DEFLATE_MAX_RATIO`]× for compressed strips, and
/// never more than the `tiff` crate's defaults), so a corrupt header cannot make it allocate
/// gigabytes.
pub fn read_depth_tiff(path: &Path) -> Result<(usize, usize, Vec<f32>), ImageError> {
    let bytes = std::fs::read(path).map_err(|e| err(path, e))?;
    check_tiff_counts(&bytes).map_err(|reason| err(path, reason))?;
    let file_len = bytes.len();
    let mut limits = tiff::decoder::Limits::default();
    let most = file_len
        .saturating_mul(DEFLATE_MAX_RATIO)
        .saturating_add(1 << 16);
    limits.decoding_buffer_size = limits.decoding_buffer_size.min(most);
    limits.intermediate_buffer_size = limits.intermediate_buffer_size.min(most);
    limits.ifd_value_size = limits.ifd_value_size.min(file_len);
    let mut dec = tiff::decoder::Decoder::new(std::io::Cursor::new(&bytes))
        .map_err(|e| err(path, e))?
        .with_limits(limits);
    let (w, h) = dec.dimensions().map_err(|e| err(path, e))?;
    match dec.read_image().map_err(|e| err(path, e))? {
        tiff::decoder::DecodingResult::F32(v) if v.len() as u64 == u64::from(w) * u64::from(h) => {
            Ok((w as usize, h as usize, v))
        }
        _ => Err(err(path, "not a single-channel float32 TIFF")),
    }
}

/// Checks that no entry of a TIFF's first IFD declares more values than the file has bytes:
/// the `tiff` decoder reads that IFD with its default limits, reserving up to 256 MiB for one
/// entry's values whatever the file holds.
fn check_tiff_counts(b: &[u8]) -> Result<(), String> {
    let little = match b.get(..2) {
        Some(b"II") => true,
        Some(b"MM") => false,
        _ => return Err("not a TIFF (no II/MM byte order mark)".into()),
    };
    let uint = |at: usize, width: usize| -> Result<u64, String> {
        let f = b
            .get(at..at.saturating_add(width))
            .ok_or_else(|| format!("truncated TIFF: {width} bytes at offset {at}"))?;
        let mut v = 0u64;
        for k in 0..width {
            let byte = if little { f[width - 1 - k] } else { f[k] };
            v = (v << 8) | u64::from(byte);
        }
        Ok(v)
    };
    let offset = |v: u64| usize::try_from(v).unwrap_or(usize::MAX);
    // (first IFD offset, entry-count width, entry size, value-count width)
    let (ifd, count_width, entry_size, values_width) = match uint(2, 2)? {
        42 => (offset(uint(4, 4)?), 2, 12, 4),
        43 => (offset(uint(8, 8)?), 8, 20, 8),
        v => return Err(format!("not a TIFF (version {v})")),
    };
    let entries = uint(ifd, count_width)?;
    let first = ifd.saturating_add(count_width);
    if entries.saturating_mul(entry_size as u64) > b.len().saturating_sub(first) as u64 {
        return Err(format!(
            "the first IFD declares {entries} entries, more than the {}-byte file holds",
            b.len()
        ));
    }
    for i in 0..entries as usize {
        let e = first + i * entry_size;
        let (tag, values) = (uint(e, 2)?, uint(e + 4, values_width)?);
        if values > b.len() as u64 {
            return Err(format!(
                "IFD entry {i} (tag {tag}) declares {values} values, more than the {}-byte \
                 file holds",
                b.len()
            ));
        }
    }
    Ok(())
}

/// Maps depth (metres) to a grey image: near = bright, far = dark, 0 (no data) = black.
pub fn depth_to_gray(depth_m: &[f32], width: usize, height: usize) -> RgbImage {
    let valid = depth_m.iter().copied().filter(|&d| d > 0.0);
    let (lo, hi) = valid.fold((f32::MAX, f32::MIN), |(a, b), d| (a.min(d), b.max(d)));
    let span = (hi - lo).max(1e-6);
    let data = depth_m
        .iter()
        .map(|&d| {
            if d > 0.0 {
                let v = (255.0 * (1.0 - (d - lo) / span) * 0.8 + 40.0) as u8;
                [v, v, v]
            } else {
                [0, 0, 0]
            }
        })
        .collect();
    RgbImage::from_pixels(width, height, data)
}

/// 5×7 glyph rows (bit 4 = leftmost column).
fn glyph(c: char) -> [u8; 7] {
    match c {
        'A' => [0x0E, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11],
        'B' => [0x1E, 0x11, 0x11, 0x1E, 0x11, 0x11, 0x1E],
        'C' => [0x0E, 0x11, 0x10, 0x10, 0x10, 0x11, 0x0E],
        'D' => [0x1E, 0x11, 0x11, 0x11, 0x11, 0x11, 0x1E],
        'E' => [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x1F],
        'F' => [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x10],
        'G' => [0x0E, 0x11, 0x10, 0x17, 0x11, 0x11, 0x0F],
        'H' => [0x11, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11],
        'I' => [0x0E, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E],
        'J' => [0x07, 0x02, 0x02, 0x02, 0x02, 0x12, 0x0C],
        'K' => [0x11, 0x12, 0x14, 0x18, 0x14, 0x12, 0x11],
        'L' => [0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1F],
        'M' => [0x11, 0x1B, 0x15, 0x15, 0x11, 0x11, 0x11],
        'N' => [0x11, 0x11, 0x19, 0x15, 0x13, 0x11, 0x11],
        'O' => [0x0E, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E],
        'P' => [0x1E, 0x11, 0x11, 0x1E, 0x10, 0x10, 0x10],
        'Q' => [0x0E, 0x11, 0x11, 0x11, 0x15, 0x12, 0x0D],
        'R' => [0x1E, 0x11, 0x11, 0x1E, 0x14, 0x12, 0x11],
        'S' => [0x0F, 0x10, 0x10, 0x0E, 0x01, 0x01, 0x1E],
        'T' => [0x1F, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04],
        'U' => [0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E],
        'V' => [0x11, 0x11, 0x11, 0x11, 0x11, 0x0A, 0x04],
        'W' => [0x11, 0x11, 0x11, 0x15, 0x15, 0x15, 0x0A],
        'X' => [0x11, 0x11, 0x0A, 0x04, 0x0A, 0x11, 0x11],
        'Y' => [0x11, 0x11, 0x11, 0x0A, 0x04, 0x04, 0x04],
        'Z' => [0x1F, 0x01, 0x02, 0x04, 0x08, 0x10, 0x1F],
        '0' => [0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E],
        '1' => [0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E],
        '2' => [0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F],
        '3' => [0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E],
        '4' => [0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02],
        '5' => [0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E],
        '6' => [0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E],
        '7' => [0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08],
        '8' => [0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E],
        '9' => [0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C],
        '_' => [0, 0, 0, 0, 0, 0, 0x1F],
        '-' => [0, 0, 0, 0x1F, 0, 0, 0],
        '.' => [0, 0, 0, 0, 0, 0x0C, 0x0C],
        ',' => [0, 0, 0, 0, 0x0C, 0x04, 0x08],
        ':' => [0, 0x0C, 0x0C, 0, 0x0C, 0x0C, 0],
        '/' => [0, 0x01, 0x02, 0x04, 0x08, 0x10, 0],
        '(' => [0x02, 0x04, 0x08, 0x08, 0x08, 0x04, 0x02],
        ')' => [0x08, 0x04, 0x02, 0x02, 0x02, 0x04, 0x08],
        '=' => [0, 0, 0x1F, 0, 0x1F, 0, 0],
        '+' => [0, 0x04, 0x04, 0x1F, 0x04, 0x04, 0],
        '#' => [0x0A, 0x0A, 0x1F, 0x0A, 0x1F, 0x0A, 0x0A],
        '%' => [0x18, 0x19, 0x02, 0x04, 0x08, 0x13, 0x03],
        _ => [0; 7],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn png_and_tiff_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let mut img = RgbImage::new(7, 5, [1, 2, 3]);
        img.put(3, 2, [200, 100, 50]);
        let p = dir.path().join("a.png");
        img.write_png(&p).unwrap();
        assert_eq!(RgbImage::read_png(&p).unwrap(), img);
        let depth: Vec<f32> = (0..35).map(|i| i as f32 * 0.01 + 0.5).collect();
        let t = dir.path().join("d.tiff");
        write_depth_tiff(&t, 7, 5, &depth).unwrap();
        assert_eq!(read_depth_tiff(&t).unwrap(), (7, 5, depth));
        std::fs::write(&t, b"II*\0garbage").unwrap();
        assert!(read_depth_tiff(&t).is_err());
    }

    #[test]
    fn headers_declaring_more_than_the_file_holds_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        // A valid 1×1 PNG whose IHDR (CRC fixed) claims 65535 × 65535 pixels: 12 GiB.
        let p = dir.path().join("a.png");
        RgbImage::new(1, 1, [0; 3]).write_png(&p).unwrap();
        let mut png = std::fs::read(&p).unwrap();
        png[16..24].copy_from_slice(&[0, 0, 0xff, 0xff, 0, 0, 0xff, 0xff]);
        let crc = crc32fast::hash(&png[12..29]);
        png[29..33].copy_from_slice(&crc.to_be_bytes());
        std::fs::write(&p, &png).unwrap();
        let e = RgbImage::read_png(&p).unwrap_err().to_string();
        assert!(e.contains("65535×65535"), "{e}");
        // A TIFF whose first tag claims 2³² - 1 values.
        let t = dir.path().join("d.tiff");
        write_depth_tiff(&t, 2, 2, &[0.5; 4]).unwrap();
        let mut tiff = std::fs::read(&t).unwrap();
        let ifd = u32::from_le_bytes(tiff[4..8].try_into().unwrap()) as usize;
        tiff[ifd + 2 + 4..ifd + 2 + 8].copy_from_slice(&u32::MAX.to_le_bytes());
        std::fs::write(&t, &tiff).unwrap();
        let e = read_depth_tiff(&t).unwrap_err().to_string();
        assert!(e.contains("4294967295 values"), "{e}");
    }
}
