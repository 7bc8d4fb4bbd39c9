//! The model file's arrays: written as little-endian chunks with their SHA-256, read back as a
//! stream, each checked against its length (before anything is allocated) and hash.

use crate::error::{Error, Result};
use crate::util::bf16::from_bf16;
use crate::util::digest::hex;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::path::Path;

/// One array as the header lists it.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ArrayInfo {
    pub name: String,
    pub dtype: String,
    pub len: u64,
    pub sha256: String,
}

/// An array to write, as its values; turned into little-endian bytes a chunk at a time.
pub(super) enum Blob<'a> {
    F32(&'a [f32]),
    /// bfloat16 values written as f32 (a chunk at a time: no f32 copy of the whole array).
    F32FromBf16(&'a [u16]),
    U64(&'a [u64]),
}

impl Blob<'_> {
    pub(super) fn dtype(&self) -> &'static str {
        match self {
            Blob::F32(_) | Blob::F32FromBf16(_) => "f32",
            Blob::U64(_) => "u64",
        }
    }

    pub(super) fn len(&self) -> usize {
        match self {
            Blob::F32(v) => v.len(),
            Blob::F32FromBf16(v) => v.len(),
            Blob::U64(v) => v.len(),
        }
    }

    pub(super) fn for_each_chunk(
        &self,
        mut f: impl FnMut(&[u8]) -> std::io::Result<()>,
    ) -> std::io::Result<()> {
        const N: usize = 1 << 14;
        let mut buf = Vec::with_capacity(N * 8);
        match self {
            Blob::F32(v) => {
                for c in v.chunks(N) {
                    buf.clear();
                    buf.extend(c.iter().flat_map(|x| x.to_le_bytes()));
                    f(&buf)?;
                }
            }
            Blob::F32FromBf16(v) => {
                for c in v.chunks(N) {
                    buf.clear();
                    buf.extend(c.iter().flat_map(|&x| from_bf16(x).to_le_bytes()));
                    f(&buf)?;
                }
            }
            Blob::U64(v) => {
                for c in v.chunks(N) {
                    buf.clear();
                    buf.extend(c.iter().flat_map(|x| x.to_le_bytes()));
                    f(&buf)?;
                }
            }
        }
        Ok(())
    }

    pub(super) fn sha256(&self) -> String {
        let mut h = Sha256::new();
        self.for_each_chunk(|b| {
            h.update(b);
            Ok(())
        })
        .expect("hashing does not fail");
        hex(&h.finalize())
    }
}

/// The arrays a header lists, by name and type.
#[derive(Default)]
pub(super) struct Arrays {
    pub(super) f32s: std::collections::HashMap<String, Vec<f32>>,
    pub(super) u64s: std::collections::HashMap<String, Vec<u64>>,
}

/// Read the header's arrays from `pos` on, each checked against its length (before anything is
/// allocated) and hash; the optimiser state is skipped unless `with_adam`. The file must end
/// where the last array ends.
pub(super) fn read_arrays<R: std::io::Read + std::io::Seek>(
    path: &Path,
    r: &mut R,
    list: &[ArrayInfo],
    mut pos: u64,
    total: u64,
    with_adam: bool,
) -> Result<Arrays> {
    let bad = |msg: String| Error::format(path, msg);
    let io_err = |e: std::io::Error| Error::io(path, e);
    let mut out = Arrays::default();
    let mut chunk = vec![0u8; 1 << 16];
    for a in list {
        let size: u64 = match a.dtype.as_str() {
            "f32" => 4,
            "u64" => 8,
            t => return Err(bad(format!("array '{}' has unknown dtype '{t}'", a.name))),
        };
        let n = a
            .len
            .checked_mul(size)
            .filter(|&n| pos.checked_add(n).is_some_and(|end| end <= total))
            .ok_or_else(|| {
                bad(format!(
                    "truncated: array '{}' needs {} bytes but only {} remain",
                    a.name,
                    a.len.saturating_mul(size),
                    total - pos
                ))
            })?;
        pos += n;
        if !with_adam && a.name.starts_with("adam_") {
            r.seek(std::io::SeekFrom::Start(pos)).map_err(io_err)?;
            continue;
        }
        let mut hash = Sha256::new();
        let (mut fv, mut uv) = (Vec::new(), Vec::new());
        if size == 4 {
            fv.reserve_exact(a.len as usize);
        } else {
            uv.reserve_exact(a.len as usize);
        }
        let mut left = n as usize;
        while left > 0 {
            let k = left.min(chunk.len());
            r.read_exact(&mut chunk[..k]).map_err(io_err)?;
            hash.update(&chunk[..k]);
            if size == 4 {
                fv.extend(
                    chunk[..k]
                        .chunks_exact(4)
                        .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes"))),
                );
            } else {
                uv.extend(
                    chunk[..k]
                        .chunks_exact(8)
                        .map(|c| u64::from_le_bytes(c.try_into().expect("8 bytes"))),
                );
            }
            left -= k;
        }
        if hex(&hash.finalize()) != a.sha256 {
            return Err(bad(format!(
                "corrupt: array '{}' fails its SHA-256 check",
                a.name
            )));
        }
        if size == 4 {
            out.f32s.insert(a.name.clone(), fv);
        } else {
            out.u64s.insert(a.name.clone(), uv);
        }
    }
    if pos != total {
        return Err(bad(format!(
            "{} unexpected bytes after the last array",
            total - pos
        )));
    }
    Ok(out)
}
