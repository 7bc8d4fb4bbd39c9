//! The [`Segmenter`]: MobileSAM's encoder (once per image, cached) and decoder (once per prompt
//! set) as ONNX Runtime sessions.

use super::cache::{embedding_key, Embedding, EmbeddingCache, EMBED_DIM, EMBED_LEN, EMBED_SIDE};
use super::mask::Mask;
use super::preprocess::{encoder_input, INPUT_SIZE};
use super::prompt::{Prompts, LOW_RES};
use super::runtime::runtime;
use super::INSTALL_HINT;
use crate::error::{Error, Result};
use crate::util::digest::sha256_file;
use image::RgbImage;
use ort::environment::Environment;
use ort::session::builder::GraphOptimizationLevel;
use ort::session::Session;
use ort::value::TensorRef;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// How to build a [`Segmenter`].
#[derive(Clone, Debug, Default)]
pub struct SegmenterOptions {
    /// ONNX Runtime intra-op threads; 0 = the number of available cores.
    pub threads: usize,
    /// Folder for the on-disk embedding cache; None = memory only.
    pub disk_cache: Option<PathBuf>,
}

impl SegmenterOptions {
    /// Threads actually used.
    pub fn resolved_threads(&self) -> usize {
        if self.threads > 0 {
            self.threads
        } else {
            std::thread::available_parallelism()
                .map(|n| n.get())
                .unwrap_or(1)
        }
    }
}

/// What `embed_timed` did.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct EmbedInfo {
    /// Served from the cache (no encoder run).
    pub cached: bool,
    pub preprocess_seconds: f64,
    pub encoder_seconds: f64,
}

/// The MobileSAM encoder and decoder sessions plus the embedding cache. `Sync`: share one between
/// threads (sessions are behind mutexes, since `Session::run` takes `&mut self`).
pub struct Segmenter {
    encoder: Mutex<Session>,
    decoder: Mutex<Session>,
    encoder_sha256: String,
    cache: EmbeddingCache,
    encoder_runs: AtomicUsize,
    threads: usize,
    /// Seconds spent loading both sessions.
    pub load_seconds: f64,
}

const DECODER_INPUTS: [&str; 6] = [
    "image_embeddings",
    "point_coords",
    "point_labels",
    "mask_input",
    "has_mask_input",
    "orig_im_size",
];
const DECODER_OUTPUTS: [&str; 3] = ["masks", "iou_predictions", "low_res_masks"];

impl Segmenter {
    /// Explicit files: the ONNX Runtime library and the two ONNX models.
    pub fn from_files(
        lib: &Path,
        encoder: &Path,
        decoder: &Path,
        opts: &SegmenterOptions,
    ) -> Result<Self> {
        let t0 = Instant::now();
        let env = runtime(lib)?;
        let threads = opts.resolved_threads();
        let encoder_session =
            load_session(&env, encoder, threads, &["image"], &["image_embeddings"])?;
        let decoder_session =
            load_session(&env, decoder, threads, &DECODER_INPUTS, &DECODER_OUTPUTS)?;
        let encoder_sha256 = sha256_file(encoder)?;
        Ok(Segmenter {
            encoder: Mutex::new(encoder_session),
            decoder: Mutex::new(decoder_session),
            encoder_sha256,
            cache: EmbeddingCache::new(opts.disk_cache.clone()),
            encoder_runs: AtomicUsize::new(0),
            threads,
            load_seconds: t0.elapsed().as_secs_f64(),
        })
    }

    /// How many times the encoder actually ran (cache hits do not count).
    pub fn encoder_runs(&self) -> usize {
        self.encoder_runs.load(Ordering::SeqCst)
    }
    pub fn threads(&self) -> usize {
        self.threads
    }
    pub fn cache(&self) -> &EmbeddingCache {
        &self.cache
    }
    pub fn model_sha256(&self) -> &str {
        &self.encoder_sha256
    }

    /// The image's embedding, from the cache when this image was seen before with this model.
    pub fn embed(&self, img: &RgbImage) -> Result<Arc<Embedding>> {
        self.embed_timed(img).map(|(e, _)| e)
    }

    pub fn embed_timed(&self, img: &RgbImage) -> Result<(Arc<Embedding>, EmbedInfo)> {
        if img.width() == 0 || img.height() == 0 {
            return Err(Error::invalid("cannot segment an empty (0-pixel) image"));
        }
        let key = embedding_key(img, &self.encoder_sha256);
        // A disk entry is only as good as its bytes: one for another size is a miss.
        let fits = |e: &Embedding| {
            (e.width, e.height) == img.dimensions() && e.scale.is_finite() && e.scale > 0.0
        };
        if let Some(e) = self.cache.get(&key).filter(|e| fits(e)) {
            return Ok((
                e,
                EmbedInfo {
                    cached: true,
                    ..Default::default()
                },
            ));
        }
        let t0 = Instant::now();
        let (input, scale) = encoder_input(img);
        let preprocess_seconds = t0.elapsed().as_secs_f64();
        let (data, encoder_seconds) = self.run_encoder(&input)?;
        let emb = Arc::new(Embedding {
            data,
            width: img.width(),
            height: img.height(),
            scale,
            key,
        });
        self.cache.put(emb.clone())?;
        Ok((
            emb,
            EmbedInfo {
                cached: false,
                preprocess_seconds,
                encoder_seconds,
            },
        ))
    }

    /// One encoder pass on a prepared 1 x 3 x 1024 x 1024 tensor (no cache): the benchmark's unit.
    pub fn run_encoder(&self, input: &[f32]) -> Result<(Vec<f32>, f64)> {
        let s = INPUT_SIZE as usize;
        if input.len() != 3 * s * s {
            return Err(Error::invalid(format!(
                "encoder input has {} values, expected 3x{s}x{s}",
                input.len()
            )));
        }
        let tensor = TensorRef::from_array_view(([1usize, 3, s, s], input)).map_err(ort_err)?;
        let mut session = self.encoder.lock().unwrap_or_else(|e| e.into_inner());
        let t0 = Instant::now();
        let out = session
            .run(ort::inputs!["image" => tensor])
            .map_err(|e| Error::external("SAM encoder", e.to_string()))?;
        let secs = t0.elapsed().as_secs_f64();
        self.encoder_runs.fetch_add(1, Ordering::SeqCst);
        let (shape, data) = out["image_embeddings"]
            .try_extract_tensor::<f32>()
            .map_err(ort_err)?;
        if **shape != [1, EMBED_DIM as i64, EMBED_SIDE as i64, EMBED_SIDE as i64]
            || data.len() != EMBED_LEN
        {
            return Err(Error::external(
                "SAM encoder",
                format!("unexpected output shape {:?}", &**shape),
            ));
        }
        Ok((data.to_vec(), secs))
    }

    /// The mask for these prompts. An empty mask is an error (nothing was found where the prompts
    /// point); use [`Segmenter::predict_allow_empty`] to get it anyway.
    pub fn predict(&self, emb: &Embedding, prompts: &Prompts) -> Result<Mask> {
        let m = self.predict_allow_empty(emb, prompts)?;
        if m.is_empty() {
            return Err(Error::invalid(format!(
                "SAM found no object for these prompts (empty mask, score {:.3}): move the point onto the object or add points",
                m.score
            )));
        }
        Ok(m)
    }

    pub fn predict_allow_empty(&self, emb: &Embedding, prompts: &Prompts) -> Result<Mask> {
        prompts.validate(emb.width, emb.height)?;
        if emb.data.len() != EMBED_LEN {
            return Err(Error::invalid("embedding has the wrong size"));
        }
        let (coords, labels) = prompts.decoder_inputs(emb.scale);
        let n = labels.len();
        let zeros;
        let (mask_in, has_mask): (&[f32], [f32; 1]) = match &prompts.mask_input {
            Some(m) => (m, [1.0]),
            None => {
                zeros = vec![0f32; LOW_RES * LOW_RES];
                (&zeros, [0.0])
            }
        };
        let size = [emb.height as f32, emb.width as f32];
        let inputs = ort::inputs![
            "image_embeddings" => tensor([1, EMBED_DIM, EMBED_SIDE, EMBED_SIDE], &emb.data)?,
            "point_coords" => tensor([1, n, 2], &coords)?,
            "point_labels" => tensor([1, n], &labels)?,
            "mask_input" => tensor([1, 1, LOW_RES, LOW_RES], mask_in)?,
            "has_mask_input" => tensor([1], &has_mask)?,
            "orig_im_size" => tensor([2], &size)?,
        ];
        let mut session = self.decoder.lock().unwrap_or_else(|e| e.into_inner());
        let t0 = Instant::now();
        let out = session
            .run(inputs)
            .map_err(|e| Error::external("SAM decoder", e.to_string()))?;
        let decoder_seconds = t0.elapsed().as_secs_f64();
        let get = |name: &str| {
            out[name]
                .try_extract_tensor::<f32>()
                .map(|(s, d)| (s.to_vec(), d))
                .map_err(ort_err)
        };
        let (mshape, logits) = get("masks")?;
        let (w, h) = (emb.width as usize, emb.height as usize);
        if logits.len() != w * h || mshape.last() != Some(&(w as i64)) {
            return Err(Error::external(
                "SAM decoder",
                format!("mask of shape {mshape:?}, expected {h}x{w}"),
            ));
        }
        let (_, iou) = get("iou_predictions")?;
        let (_, low) = get("low_res_masks")?;
        if low.len() != LOW_RES * LOW_RES || iou.is_empty() {
            return Err(Error::external("SAM decoder", "unexpected output sizes"));
        }
        Ok(Mask {
            width: emb.width,
            height: emb.height,
            bitmap: logits.iter().map(|&v| v > 0.0).collect(),
            logits: logits.to_vec(),
            score: iou[0],
            low_res: low.to_vec(),
            decoder_seconds,
        })
    }

    /// Embed (cached) and predict in one call.
    pub fn segment(&self, img: &RgbImage, prompts: &Prompts) -> Result<Mask> {
        let emb = self.embed(img)?;
        self.predict(&emb, prompts)
    }
}

fn tensor<const N: usize>(shape: [usize; N], data: &[f32]) -> Result<TensorRef<'_, f32>> {
    TensorRef::from_array_view((shape, data)).map_err(ort_err)
}

fn ort_err<R>(e: ort::Error<R>) -> Error {
    Error::external("ONNX Runtime", e.to_string())
}

/// A session for `path` with the same settings as Python onnxruntime's defaults (all graph
/// optimisations, sequential execution), checking it has the inputs and outputs SAM needs.
fn load_session(
    env: &Environment,
    path: &Path,
    threads: usize,
    inputs: &[&str],
    outputs: &[&str],
) -> Result<Session> {
    if !path.is_file() {
        return Err(Error::external(
            "SAM model",
            format!("{} not found; run `{INSTALL_HINT}`", path.display()),
        ));
    }
    let bad = |stage: &str, msg: String| Error::format(path, format!("{stage}: {msg}"));
    let session = Session::builder(env)
        .map_err(|e| bad("session options", e.to_string()))?
        .with_optimization_level(GraphOptimizationLevel::All)
        .map_err(|e| bad("optimisation level", e.to_string()))?
        .with_intra_threads(threads)
        .map_err(|e| bad("threads", e.to_string()))?
        .with_inter_threads(1)
        .map_err(|e| bad("threads", e.to_string()))?
        .commit_from_file(path)
        .map_err(|e| bad("not a model ONNX Runtime can load", e.to_string()))?;
    for name in inputs {
        if !session.inputs().iter().any(|o| o.name() == *name) {
            return Err(bad(
                "wrong model",
                format!("it has no input named {name:?}"),
            ));
        }
    }
    for name in outputs {
        if !session.outputs().iter().any(|o| o.name() == *name) {
            return Err(bad(
                "wrong model",
                format!("it has no output named {name:?}"),
            ));
        }
    }
    Ok(session)
}
