//! MobileSAM's ONNX encoder and decoder, written from the official PyTorch checkpoint
//! (`mobile_sam.pt`) without Python or PyTorch: [`torch`] reads the checkpoint (a zip of
//! raw storages and a pickled state dict, [`pickle`]), [`encoder`] and [`decoder`] build the two
//! graphs with [`graph`], and [`onnx_proto`] is the protobuf schema they are written in.
//!
//! The graphs have the reference export's inputs, outputs and opset (17) and the same operator
//! choices, so ONNX Runtime optimises them the same way; the output is deterministic (same
//! checkpoint, same bytes).

pub mod decoder;
pub mod encoder;
pub mod graph;
pub mod onnx_proto;
pub mod pickle;
pub mod quant;
pub mod torch;

use crate::error::{Error, Result};
use crate::util::atomic::make_readable;
use crate::util::digest::sha256_file;
use prost::Message;
use std::path::Path;

/// The official MobileSAM checkpoint's sha256: only this file is converted.
pub const CHECKPOINT_SHA256: &str =
    "6dbb90523a35330fedd7f1d3dfc66f995213d81b29a5ca8108dbcdd4e37d6c2f";

/// The serialised models.
pub struct SamOnnx {
    pub encoder: Vec<u8>,
    pub decoder: Vec<u8>,
    /// The int8 encoder ([`encoder::Variant::INT8`]).
    pub encoder_int8: Vec<u8>,
}

/// Check that `checkpoint` is the official MobileSAM file (by sha256), then build the models.
pub fn mobile_sam_onnx(checkpoint: &Path) -> Result<SamOnnx> {
    verify_checkpoint(checkpoint)?;
    let sd = torch::StateDict::load(checkpoint)?;
    Ok(SamOnnx {
        encoder: encoder::build(&sd)?.encode_to_vec(),
        decoder: decoder::build(&sd)?.encode_to_vec(),
        encoder_int8: encoder::build_variant(&sd, encoder::Variant::INT8)?.encode_to_vec(),
    })
}

/// The file names [`write_mobile_sam_onnx`] writes in its folder (as in the models directory).
pub const ENCODER_FILE: &str = "encoder.onnx";
pub const DECODER_FILE: &str = "decoder.onnx";
pub const ENCODER_INT8_FILE: &str = "encoder_int8.onnx";

/// [`mobile_sam_onnx`], written atomically into `out` as [`ENCODER_FILE`], [`DECODER_FILE`] and
/// [`ENCODER_INT8_FILE`]; returns their paths.
pub fn write_mobile_sam_onnx(checkpoint: &Path, out: &Path) -> Result<[std::path::PathBuf; 3]> {
    let m = mobile_sam_onnx(checkpoint)?;
    let paths = [ENCODER_FILE, DECODER_FILE, ENCODER_INT8_FILE].map(|f| out.join(f));
    for (path, bytes) in paths.iter().zip([&m.encoder, &m.decoder, &m.encoder_int8]) {
        crate::util::atomic::write_bytes_atomic(path, bytes)?;
        make_readable(path)?;
    }
    Ok(paths)
}

/// The graphs are written for this one checkpoint: anything else (a truncated download, another
/// model) is refused before it is parsed.
pub fn verify_checkpoint(checkpoint: &Path) -> Result<()> {
    let h = sha256_file(checkpoint)?;
    if h != CHECKPOINT_SHA256 {
        let size = std::fs::metadata(checkpoint).map(|m| m.len()).unwrap_or(0);
        return Err(Error::format(
            checkpoint,
            format!(
                "sha256 {h} ({size} bytes) is not the official MobileSAM checkpoint ({CHECKPOINT_SHA256}, 40728226 bytes): a truncated or different file; delete it and run `objnerf models install`"
            ),
        ));
    }
    Ok(())
}
