//! Image embeddings, and a cache of them keyed by the image's pixels and the encoder's file hash:
//! in memory (so the k objects of one run share one encoder pass per view) and on disk (so a
//! second run never encodes a view again). The encoder is the expensive part (about 1 s a view on
//! two cores; the decoder takes a few tens of milliseconds).

use crate::error::{Error, Result};
use sha2::{Digest, Sha256};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// The encoder output's shape: 256 channels on a 64 x 64 grid.
pub const EMBED_DIM: usize = 256;
pub const EMBED_SIDE: usize = 64;
pub const EMBED_LEN: usize = EMBED_DIM * EMBED_SIDE * EMBED_SIDE;

/// One image's embedding plus what the decoder needs to map prompts and masks back.
#[derive(Clone, Debug)]
pub struct Embedding {
    /// 1 x 256 x 64 x 64, row-major.
    pub data: Vec<f32>,
    pub width: u32,
    pub height: u32,
    /// Resized / original (SAM resizes the longest side to 1024).
    pub scale: f64,
    /// The cache key (hex sha256 of the pixels and the model).
    pub key: String,
}

/// The cache key: sha256 over the image size, its RGB bytes and the encoder's sha256.
pub fn embedding_key(img: &image::RgbImage, model_sha256: &str) -> String {
    let mut h = Sha256::new();
    h.update(b"objnerf-sam-embedding-v1");
    h.update(img.width().to_le_bytes());
    h.update(img.height().to_le_bytes());
    h.update(img.as_raw());
    h.update(model_sha256.as_bytes());
    crate::util::digest::hex(&h.finalize())
}

const MAGIC: &[u8; 8] = b"ONSAMEMB";

/// Memory + optional disk cache. Shared between threads.
#[derive(Debug, Default)]
pub struct EmbeddingCache {
    mem: Mutex<HashMap<String, Arc<Embedding>>>,
    disk: Option<PathBuf>,
    /// At most this many embeddings are kept in memory (4 MiB each); older ones are dropped in no
    /// particular order, since the disk copy remains.
    max_in_memory: usize,
}

impl EmbeddingCache {
    /// `disk`: the folder for `.emb` files (`$OBJNERF_HOME/cache/embeddings`), or None for memory only.
    pub fn new(disk: Option<PathBuf>) -> Self {
        EmbeddingCache {
            mem: Mutex::new(HashMap::new()),
            disk,
            max_in_memory: 64,
        }
    }

    pub fn disk_dir(&self) -> Option<&Path> {
        self.disk.as_deref()
    }

    fn file(&self, key: &str) -> Option<PathBuf> {
        self.disk.as_ref().map(|d| d.join(format!("{key}.emb")))
    }

    /// A cached embedding, from memory or disk. An unreadable or corrupt disk entry is a miss
    /// (it will be recomputed and overwritten), never an error.
    pub fn get(&self, key: &str) -> Option<Arc<Embedding>> {
        if let Some(e) = self.mem.lock().ok()?.get(key) {
            return Some(e.clone());
        }
        let path = self.file(key)?;
        let bytes = std::fs::read(&path).ok()?;
        let emb = Arc::new(decode(&bytes, key)?);
        self.put_mem(emb.clone());
        Some(emb)
    }

    /// Store in memory and (if configured) on disk. A failed disk write is reported, since
    /// it would silently cost an encoder pass next time.
    pub fn put(&self, emb: Arc<Embedding>) -> Result<()> {
        self.put_mem(emb.clone());
        if let Some(path) = self.file(&emb.key) {
            crate::util::atomic::write_bytes_atomic(&path, &encode(&emb))?;
        }
        Ok(())
    }

    fn put_mem(&self, emb: Arc<Embedding>) {
        if let Ok(mut m) = self.mem.lock() {
            if m.len() >= self.max_in_memory {
                if let Some(k) = m.keys().next().cloned() {
                    m.remove(&k);
                }
            }
            m.insert(emb.key.clone(), emb);
        }
    }

    /// Forget what is in memory (the disk copies stay): lets a test prove the disk path works.
    pub fn clear_memory(&self) {
        if let Ok(mut m) = self.mem.lock() {
            m.clear();
        }
    }
}

/// `MAGIC`, u32 width, u32 height, f64 scale, u32 len, then len f32, all little-endian.
fn encode(e: &Embedding) -> Vec<u8> {
    let mut b = Vec::with_capacity(28 + 4 * e.data.len());
    b.extend_from_slice(MAGIC);
    b.extend_from_slice(&e.width.to_le_bytes());
    b.extend_from_slice(&e.height.to_le_bytes());
    b.extend_from_slice(&e.scale.to_le_bytes());
    b.extend_from_slice(&(e.data.len() as u32).to_le_bytes());
    for v in &e.data {
        b.extend_from_slice(&v.to_le_bytes());
    }
    b
}

fn decode(b: &[u8], key: &str) -> Option<Embedding> {
    if b.len() < 28 || &b[..8] != MAGIC {
        return None;
    }
    let u32_at = |i: usize| u32::from_le_bytes(b[i..i + 4].try_into().unwrap());
    let width = u32_at(8);
    let height = u32_at(12);
    let scale = f64::from_le_bytes(b[16..24].try_into().unwrap());
    let len = u32_at(24) as usize;
    if len != EMBED_LEN || b.len() != 28 + 4 * len {
        return None;
    }
    let data: Vec<f32> = b[28..]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
        .collect();
    // A flipped bit can make a NaN, which SAM would turn into a silently empty mask.
    if !data.iter().all(|v| v.is_finite()) {
        return None;
    }
    Some(Embedding {
        data,
        width,
        height,
        scale,
        key: key.to_string(),
    })
}

/// Remove every cached embedding on disk; returns how many files went.
pub fn clear_disk(dir: &Path) -> Result<usize> {
    let Ok(rd) = std::fs::read_dir(dir) else {
        return Ok(0);
    };
    let mut n = 0;
    for e in rd.flatten() {
        let p = e.path();
        if p.extension().is_some_and(|x| x == "emb") {
            std::fs::remove_file(&p).map_err(|err| Error::io(&p, err))?;
            n += 1;
        }
    }
    Ok(n)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roundtrip_and_corrupt() {
        let dir = tempfile::tempdir().unwrap();
        let cache = EmbeddingCache::new(Some(dir.path().to_path_buf()));
        let e = Embedding {
            data: (0..EMBED_LEN).map(|i| i as f32 * 0.5).collect(),
            width: 7,
            height: 3,
            scale: 1024.0 / 7.0,
            key: "abc".into(),
        };
        cache.put(Arc::new(e.clone())).unwrap();
        cache.clear_memory();
        let back = cache.get("abc").unwrap();
        assert_eq!(back.data, e.data);
        assert_eq!((back.width, back.height, back.scale), (7, 3, e.scale));
        std::fs::write(dir.path().join("abc.emb"), b"ONSAMEMBgarbage").unwrap();
        cache.clear_memory();
        assert!(cache.get("abc").is_none());
        // A NaN (a flipped exponent bit) is a miss too.
        let mut bytes = encode(&e);
        bytes[28 + 4 * 9 + 3] = 0x7f;
        bytes[28 + 4 * 9 + 2] = 0xc0;
        std::fs::write(dir.path().join("abc.emb"), bytes).unwrap();
        assert!(cache.get("abc").is_none());
        assert_eq!(clear_disk(dir.path()).unwrap(), 1);
    }
}
