//! Minimal `.npy` / `.npz` I/O: numpy's array format and its zip container, written as an
//! uncompressed (stored) zip so that `numpy.load` reads it without any zip library here.
//!
//! Supported element types: little-endian `f4`, `f8`, `u4`, `u8`, `i4`, `i8`; C order (or
//! one-dimensional). Reading accepts stored (uncompressed) entries only: write with
//! `numpy.savez`, not `numpy.savez_compressed`.
//!
//! Why not a crate: `npyz` (0.8, feature `npz`) reads and writes `.npz`, including what
//! `numpy.savez_compressed` writes, but on non-wasm targets it pulls `zip` 0.6 with all of that
//! crate's default features (bzip2 and a second zstd, both C builds; AES, PBKDF2, SHA-1, HMAC;
//! `time`) plus `pest`/`pest_derive` and `num-bigint` for parsing headers: about 60 extra
//! crates, none of which `default-features = false` can drop. Everything this crate exchanges
//! is written by this module (or by `numpy.savez`), a few hundred lines using only `crc32fast`;
//! supporting compressed input is not worth that build.
//!
//! ```
//! use lgdm_pointcloud::npz::{read_npz, write_npz, NpyData, NpyRef};
//! let dir = tempfile::tempdir().unwrap();
//! let path = dir.path().join("a.npz");
//! let x = [1.0f32, 2.0, 3.0, 4.0];
//! write_npz(&path, &[("x", NpyRef::F32(&x, &[2, 2]))]).unwrap();
//! let arrays = read_npz(&path).unwrap();
//! assert_eq!(arrays[0].name, "x");
//! assert_eq!(arrays[0].shape, vec![2, 2]);
//! assert_eq!(arrays[0].data, NpyData::F32(x.to_vec()));
//! ```

use std::path::{Path, PathBuf};

/// Errors reading or writing `.npz` files.
#[derive(Debug, thiserror::Error)]
pub enum NpzError {
    /// File-system error.
    #[error("cannot access {}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The file is not a readable `.npz` (or holds something this reader does not support).
    #[error("{}: {reason}", path.display())]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
}

/// A borrowed array to write: data and shape (row-major).
#[derive(Debug, Clone, Copy)]
pub enum NpyRef<'a> {
    /// 32-bit floats.
    F32(&'a [f32], &'a [usize]),
    /// Unsigned 32-bit integers.
    U32(&'a [u32], &'a [usize]),
    /// Unsigned 64-bit integers.
    U64(&'a [u64], &'a [usize]),
}

/// Owned array data read from a file.
#[derive(Debug, Clone, PartialEq)]
pub enum NpyData {
    /// `<f4`
    F32(Vec<f32>),
    /// `<f8`
    F64(Vec<f64>),
    /// `<u4`
    U32(Vec<u32>),
    /// `<u8`
    U64(Vec<u64>),
    /// `<i4`
    I32(Vec<i32>),
    /// `<i8`
    I64(Vec<i64>),
}

impl NpyData {
    /// Number of elements.
    pub fn len(&self) -> usize {
        match self {
            NpyData::F32(v) => v.len(),
            NpyData::F64(v) => v.len(),
            NpyData::U32(v) => v.len(),
            NpyData::U64(v) => v.len(),
            NpyData::I32(v) => v.len(),
            NpyData::I64(v) => v.len(),
        }
    }

    /// Whether there are no elements.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The numpy dtype (`descr`) the values were read from: `<f4`, `<f8`, `<u4`, `<u8`, `<i4`
    /// or `<i8`.
    pub fn dtype(&self) -> &'static str {
        match self {
            NpyData::F32(_) => "<f4",
            NpyData::F64(_) => "<f8",
            NpyData::U32(_) => "<u4",
            NpyData::U64(_) => "<u8",
            NpyData::I32(_) => "<i4",
            NpyData::I64(_) => "<i8",
        }
    }

    /// The values as non-negative integers (`None` if a value is negative or fractional).
    pub fn to_u64(&self) -> Option<Vec<u64>> {
        match self {
            NpyData::U32(v) => Some(v.iter().map(|&x| u64::from(x)).collect()),
            NpyData::U64(v) => Some(v.clone()),
            NpyData::I32(v) => v.iter().map(|&x| u64::try_from(x).ok()).collect(),
            NpyData::I64(v) => v.iter().map(|&x| u64::try_from(x).ok()).collect(),
            NpyData::F32(_) | NpyData::F64(_) => None,
        }
    }

    /// The values as `f32` (integers converted).
    pub fn to_f32(&self) -> Vec<f32> {
        match self {
            NpyData::F32(v) => v.clone(),
            NpyData::F64(v) => v.iter().map(|&x| x as f32).collect(),
            NpyData::U32(v) => v.iter().map(|&x| x as f32).collect(),
            NpyData::U64(v) => v.iter().map(|&x| x as f32).collect(),
            NpyData::I32(v) => v.iter().map(|&x| x as f32).collect(),
            NpyData::I64(v) => v.iter().map(|&x| x as f32).collect(),
        }
    }
}

/// One named array read from an `.npz`.
#[derive(Debug, Clone, PartialEq)]
pub struct NpyArray {
    /// Name without the `.npy` suffix.
    pub name: String,
    /// Shape (row-major).
    pub shape: Vec<usize>,
    /// Elements.
    pub data: NpyData,
}

/// Serialises one array in `.npy` format version 1.0.
pub fn npy_bytes(array: NpyRef<'_>) -> Vec<u8> {
    let (descr, shape, elem) = match array {
        NpyRef::F32(_, s) => ("<f4", s, 4),
        NpyRef::U32(_, s) => ("<u4", s, 4),
        NpyRef::U64(_, s) => ("<u8", s, 8),
    };
    let shape_txt = match shape.len() {
        1 => format!("({},)", shape[0]),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(|d| d.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    };
    let mut header =
        format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape_txt}, }}");
    // Magic (6) + version (2) + header length (2) + header + '\n' is a multiple of 64.
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let count: usize = shape.iter().product();
    let mut out = Vec::with_capacity(10 + header.len() + count * elem);
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    match array {
        NpyRef::F32(d, _) => d
            .iter()
            .for_each(|v| out.extend_from_slice(&v.to_le_bytes())),
        NpyRef::U32(d, _) => d
            .iter()
            .for_each(|v| out.extend_from_slice(&v.to_le_bytes())),
        NpyRef::U64(d, _) => d
            .iter()
            .for_each(|v| out.extend_from_slice(&v.to_le_bytes())),
    }
    out
}

const DOS_DATE_1980_01_01: u16 = (1 << 5) | 1;

/// Writes arrays as an uncompressed `.npz` (entries `<name>.npy`), through a temp file renamed
/// into place. Each array's data length must equal the product of its shape.
pub fn write_npz(path: &Path, arrays: &[(&str, NpyRef<'_>)]) -> Result<(), NpzError> {
    let format = |reason: String| NpzError::Format {
        path: path.to_path_buf(),
        reason,
    };
    let mut out: Vec<u8> = Vec::new();
    let mut central: Vec<u8> = Vec::new();
    for (name, array) in arrays {
        let (len, shape) = match array {
            NpyRef::F32(d, s) => (d.len(), *s),
            NpyRef::U32(d, s) => (d.len(), *s),
            NpyRef::U64(d, s) => (d.len(), *s),
        };
        if shape.iter().product::<usize>() != len {
            return Err(format(format!(
                "array `{name}` has {len} elements but shape {shape:?}"
            )));
        }
        let body = npy_bytes(*array);
        let file_name = format!("{name}.npy");
        let crc = crc32fast::hash(&body);
        let offset = out.len();
        let (size, offset32) = match (u32::try_from(body.len()), u32::try_from(offset)) {
            (Ok(s), Ok(o)) => (s, o),
            _ => {
                return Err(format(
                    "archive larger than 4 GiB (zip64 is not supported)".into(),
                ));
            }
        };
        // Local file header.
        out.extend_from_slice(&0x0403_4b50u32.to_le_bytes());
        for v in [20u16, 0, 0, 0, DOS_DATE_1980_01_01] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&crc.to_le_bytes());
        out.extend_from_slice(&size.to_le_bytes());
        out.extend_from_slice(&size.to_le_bytes());
        out.extend_from_slice(&(file_name.len() as u16).to_le_bytes());
        out.extend_from_slice(&0u16.to_le_bytes());
        out.extend_from_slice(file_name.as_bytes());
        out.extend_from_slice(&body);
        // Central directory entry.
        central.extend_from_slice(&0x0201_4b50u32.to_le_bytes());
        for v in [20u16, 20, 0, 0, 0, DOS_DATE_1980_01_01] {
            central.extend_from_slice(&v.to_le_bytes());
        }
        central.extend_from_slice(&crc.to_le_bytes());
        central.extend_from_slice(&size.to_le_bytes());
        central.extend_from_slice(&size.to_le_bytes());
        central.extend_from_slice(&(file_name.len() as u16).to_le_bytes());
        for v in [0u16, 0, 0, 0] {
            central.extend_from_slice(&v.to_le_bytes()); // extra, comment, disk, internal attrs
        }
        central.extend_from_slice(&0u32.to_le_bytes()); // external attrs
        central.extend_from_slice(&offset32.to_le_bytes());
        central.extend_from_slice(file_name.as_bytes());
    }
    let cd_offset =
        u32::try_from(out.len()).map_err(|_| format("archive larger than 4 GiB".into()))?;
    out.extend_from_slice(&central);
    out.extend_from_slice(&0x0605_4b50u32.to_le_bytes());
    let n = arrays.len() as u16;
    for v in [0u16, 0, n, n] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out.extend_from_slice(&(central.len() as u32).to_le_bytes());
    out.extend_from_slice(&cd_offset.to_le_bytes());
    out.extend_from_slice(&0u16.to_le_bytes());
    lgdm_base::fs::write_atomic(path, |w| std::io::Write::write_all(w, &out)).map_err(|source| {
        NpzError::Io {
            path: path.to_path_buf(),
            source,
        }
    })
}

fn u16_at(b: &[u8], o: usize) -> Option<u16> {
    Some(u16::from_le_bytes(b.get(o..o + 2)?.try_into().ok()?))
}

fn u32_at(b: &[u8], o: usize) -> Option<u32> {
    Some(u32::from_le_bytes(b.get(o..o + 4)?.try_into().ok()?))
}

/// Reads every array of an uncompressed `.npz`, in archive order.
pub fn read_npz(path: &Path) -> Result<Vec<NpyArray>, NpzError> {
    let bytes = std::fs::read(path).map_err(|source| NpzError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let format = |reason: String| NpzError::Format {
        path: path.to_path_buf(),
        reason,
    };
    let truncated = || format("truncated or not a zip archive".to_string());
    // End of central directory: scan back over a possible comment.
    let eocd = (0..bytes.len().saturating_sub(21))
        .rev()
        .take(22 + 65_536)
        .find(|&i| u32_at(&bytes, i) == Some(0x0605_4b50))
        .ok_or_else(|| {
            format("no zip end-of-central-directory record (not an .npz, or truncated)".into())
        })?;
    let entries = u16_at(&bytes, eocd + 10).ok_or_else(truncated)? as usize;
    let cd_offset = u32_at(&bytes, eocd + 16).ok_or_else(truncated)? as usize;
    // Each entry takes at least a 46-byte central directory record: no more can be real.
    let mut out = Vec::with_capacity(entries.min(bytes.len() / 46));
    let mut p = cd_offset;
    for _ in 0..entries {
        if u32_at(&bytes, p) != Some(0x0201_4b50) {
            return Err(format("corrupt zip central directory".into()));
        }
        let method = u16_at(&bytes, p + 10).ok_or_else(truncated)?;
        let crc = u32_at(&bytes, p + 16).ok_or_else(truncated)?;
        let csize = u32_at(&bytes, p + 20).ok_or_else(truncated)? as usize;
        let name_len = u16_at(&bytes, p + 28).ok_or_else(truncated)? as usize;
        let extra_len = u16_at(&bytes, p + 30).ok_or_else(truncated)? as usize;
        let comment_len = u16_at(&bytes, p + 32).ok_or_else(truncated)? as usize;
        let local = u32_at(&bytes, p + 42).ok_or_else(truncated)? as usize;
        let name = bytes.get(p + 46..p + 46 + name_len).ok_or_else(truncated)?;
        let name = String::from_utf8_lossy(name).into_owned();
        p += 46 + name_len + extra_len + comment_len;
        if method != 0 {
            return Err(format(format!(
                "entry `{name}` is compressed (method {method}); only stored entries are supported \
                 (write with numpy.savez, not savez_compressed)"
            )));
        }
        if u32_at(&bytes, local) != Some(0x0403_4b50) {
            return Err(format(format!("entry `{name}`: bad local header")));
        }
        let l_name = u16_at(&bytes, local + 26).ok_or_else(truncated)? as usize;
        let l_extra = u16_at(&bytes, local + 28).ok_or_else(truncated)? as usize;
        let start = local + 30 + l_name + l_extra;
        let body = bytes.get(start..start + csize).ok_or_else(truncated)?;
        if crc32fast::hash(body) != crc {
            return Err(format(format!(
                "entry `{name}`: CRC mismatch (corrupt file)"
            )));
        }
        let (shape, data) = parse_npy(body).map_err(|r| format(format!("entry `{name}`: {r}")))?;
        out.push(NpyArray {
            name: name.strip_suffix(".npy").unwrap_or(&name).to_string(),
            shape,
            data,
        });
    }
    Ok(out)
}

/// Parses one `.npy` body (versions 1–3).
pub fn parse_npy(body: &[u8]) -> Result<(Vec<usize>, NpyData), String> {
    if body.len() < 10 || &body[..6] != b"\x93NUMPY" {
        return Err("not an .npy array (bad magic)".into());
    }
    let (header_len, header_start) = match body[6] {
        1 => (usize::from(u16_at(body, 8).ok_or("truncated header")?), 10),
        2 | 3 => (u32_at(body, 8).ok_or("truncated header")? as usize, 12),
        v => return Err(format!("unsupported .npy version {v}")),
    };
    let header = body
        .get(header_start..header_start + header_len)
        .ok_or("truncated header")?;
    let header = std::str::from_utf8(header).map_err(|_| "header is not text")?;
    let value_after = |key: &str| -> Result<&str, String> {
        let at = header
            .find(&format!("'{key}'"))
            .ok_or(format!("header lacks `{key}`"))?;
        let rest = &header[at + key.len() + 2..];
        Ok(rest.trim_start().trim_start_matches(':').trim_start())
    };
    let descr = value_after("descr")?;
    let descr = descr
        .strip_prefix('\'')
        .and_then(|d| d.split('\'').next())
        .ok_or("bad descr")?;
    let fortran = value_after("fortran_order")?.starts_with("True");
    let shape_txt = value_after("shape")?;
    let shape_txt = shape_txt
        .strip_prefix('(')
        .and_then(|s| s.split(')').next())
        .ok_or("bad shape")?;
    let shape: Vec<usize> = shape_txt
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| {
            s.parse::<usize>()
                .map_err(|_| format!("bad shape entry `{s}`"))
        })
        .collect::<Result<_, _>>()?;
    if fortran && shape.iter().filter(|&&d| d > 1).count() > 1 {
        return Err("Fortran-order arrays are not supported".into());
    }
    let data = &body[header_start + header_len..];
    // The element count, and the bytes it needs, checked against the bytes present before
    // anything is allocated (a corrupt shape can overflow `usize`).
    let count = shape
        .iter()
        .try_fold(1usize, |acc, &d| acc.checked_mul(d))
        .ok_or_else(|| format!("shape {shape:?} has more elements than memory can address"))?;
    let need = |size: usize| -> Result<&[u8], String> {
        count
            .checked_mul(size)
            .and_then(|bytes| data.get(..bytes))
            .ok_or_else(|| {
                format!(
                    "data holds {} bytes, shape {shape:?} needs {count} × {size}",
                    data.len()
                )
            })
    };
    let parsed = match descr {
        "<f4" => NpyData::F32(
            need(4)?
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
                .collect(),
        ),
        "<f8" => NpyData::F64(
            need(8)?
                .chunks_exact(8)
                .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
                .collect(),
        ),
        "<u4" => NpyData::U32(
            need(4)?
                .chunks_exact(4)
                .map(|c| u32::from_le_bytes(c.try_into().unwrap()))
                .collect(),
        ),
        "<u8" => NpyData::U64(
            need(8)?
                .chunks_exact(8)
                .map(|c| u64::from_le_bytes(c.try_into().unwrap()))
                .collect(),
        ),
        "<i4" => NpyData::I32(
            need(4)?
                .chunks_exact(4)
                .map(|c| i32::from_le_bytes(c.try_into().unwrap()))
                .collect(),
        ),
        "<i8" => NpyData::I64(
            need(8)?
                .chunks_exact(8)
                .map(|c| i64::from_le_bytes(c.try_into().unwrap()))
                .collect(),
        ),
        other => return Err(format!("unsupported dtype `{other}`")),
    };
    Ok((shape, parsed))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_is_64_byte_aligned() {
        let b = npy_bytes(NpyRef::U32(&[1, 2, 3], &[3]));
        let header_len = u16::from_le_bytes([b[8], b[9]]) as usize;
        assert_eq!((10 + header_len) % 64, 0);
        assert_eq!(b.len(), 10 + header_len + 12);
    }

    #[test]
    fn shapes_are_checked_against_the_data_before_allocating() {
        let npy = |shape: &str| {
            let header =
                format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {shape}, }}\n");
            let mut b = b"\x93NUMPY\x01\x00".to_vec();
            b.extend_from_slice(&(header.len() as u16).to_le_bytes());
            b.extend_from_slice(header.as_bytes());
            b.extend_from_slice(&[0; 16]);
            b
        };
        assert!(parse_npy(&npy("(2, 2)")).is_ok());
        // 2³² × 2³² wraps to 0 elements; 2⁶⁴ - 1 elements need 2⁶⁶ bytes.
        for shape in [
            "(4294967296, 4294967296)",
            "(18446744073709551615,)",
            "(5,)",
        ] {
            assert!(parse_npy(&npy(shape)).is_err(), "{shape}");
        }
    }

    #[test]
    fn corrupt_and_compressed_archives_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.npz");
        write_npz(&path, &[("x", NpyRef::U64(&[7, 8], &[2]))]).unwrap();
        let mut bytes = std::fs::read(&path).unwrap();
        // Flip a data byte: CRC mismatch.
        let pos = bytes.len() / 2;
        bytes[pos] ^= 0xff;
        std::fs::write(&path, &bytes).unwrap();
        assert!(read_npz(&path).is_err());
        std::fs::write(&path, &bytes[..20]).unwrap();
        assert!(read_npz(&path).is_err());
        std::fs::write(&path, b"").unwrap();
        assert!(read_npz(&path).is_err());
        assert!(write_npz(&path, &[("x", NpyRef::U64(&[7, 8], &[3]))]).is_err());
    }
}
