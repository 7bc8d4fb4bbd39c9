//! SAM as the multi-view propagation's [`ViewSegmenter`]: a scene's view index becomes its image,
//! decoded once and embedded once (the embedding cache makes the k objects of a run, and later
//! runs, share the encoder pass).

use super::types::{ClickAlternatives, PointPrompt, ViewMask, ViewSegmenter};
use crate::error::Result;
use crate::sam::zoom::ZoomOptions;
use crate::sam::{Embedding, Point, Prompts, Segmenter};
use crate::scene::io::read_rgb;
use crate::scene::Scene;
use crate::util::{Detail, Progress};
use std::sync::Arc;

pub struct SamViews<'a> {
    seg: &'a Segmenter,
    /// The last view's embedding: the propagation asks for the same view several times in a row
    /// (one per object), so this skips decoding and hashing the image again.
    last: Option<(usize, Arc<Embedding>)>,
    /// Re-segment small objects on a crop ([`Segmenter::segment_zoomed`]): sharper edges for one
    /// more encoder pass per small object and view.
    zoom: Option<ZoomOptions>,
    /// Decoder passes that feed the previous pass's low-res logits back as `mask_input` with the
    /// same prompts (SAM's iterative refinement). One pass fills the parts a box-and-points
    /// prompt misses (lego's shovel): lego one-click mIoU 0.959 -> 0.976 over 100 views, demo
    /// mIoU(ok) up by 0.00-0.012 per object and obstruction F1 0.933 -> 1.0; one more decoder
    /// run (tens of ms) per mask.
    refine: usize,
    /// Told once a view (not per refinement pass), with the view's name.
    progress: Option<&'a dyn Progress>,
    /// Views segmented so far (the progress position).
    done: u64,
    /// Time spent in the encoder (with its preprocessing) and in the decoder, seconds.
    pub encoder_seconds: f64,
    pub decoder_seconds: f64,
}

impl<'a> SamViews<'a> {
    pub fn new(seg: &'a Segmenter) -> Self {
        SamViews {
            seg,
            last: None,
            zoom: None,
            refine: 1,
            progress: None,
            done: 0,
            encoder_seconds: 0.0,
            decoder_seconds: 0.0,
        }
    }

    pub fn with_zoom(mut self, zoom: Option<ZoomOptions>) -> Self {
        self.zoom = zoom;
        self
    }

    pub fn with_progress(mut self, progress: &'a dyn Progress) -> Self {
        self.progress = Some(progress);
        self
    }

    pub fn with_refine(mut self, passes: usize) -> Self {
        self.refine = passes;
        self
    }

    fn embedding(&mut self, scene: &Scene, view: usize) -> Result<Arc<Embedding>> {
        if let Some((v, e)) = &self.last {
            if *v == view {
                return Ok(e.clone());
            }
        }
        let img = read_rgb(&scene.images[view].path)?;
        let (e, info) = self.seg.embed_timed(&img)?;
        self.encoder_seconds += info.encoder_seconds + info.preprocess_seconds;
        self.last = Some((view, e.clone()));
        Ok(e)
    }
}

impl ViewSegmenter for SamViews<'_> {
    /// An empty mask is returned as such (not an error): for the propagation it is evidence that
    /// the object is hidden in this view.
    fn segment(
        &mut self,
        scene: &Scene,
        view: usize,
        prompts: &[PointPrompt],
        bbox: Option<[f64; 4]>,
    ) -> Result<ViewMask> {
        let emb = self.embedding(scene, view)?;
        let p = sam_prompts(prompts, bbox);
        let mut m = match &self.zoom {
            // Zooming needs the image and a non-empty first mask; an empty one stays empty.
            Some(z) => {
                let img = read_rgb(&scene.images[view].path)?;
                match self.seg.segment_zoomed(&img, &p, z) {
                    Ok(m) => m,
                    Err(_) => self.seg.predict_allow_empty(&emb, &p)?,
                }
            }
            None => self.seg.predict_allow_empty(&emb, &p)?,
        };
        self.decoder_seconds += m.decoder_seconds;
        // A zoomed mask's low-res logits belong to its crop, so zoom and refine do not mix. One
        // click without a box makes the decoder pick among its multimask outputs by score, and
        // fed back that choice can flip to a larger mask (fox: the whole wall), so a lone
        // click is not refined; SAM itself refines with single-mask output only.
        let single_click = p.points.len() == 1 && p.bbox.is_none();
        let passes = if self.zoom.is_none() && !single_click {
            self.refine
        } else {
            0
        };
        for _ in 0..passes {
            if m.is_empty() {
                break;
            }
            let again = Prompts {
                mask_input: Some(m.low_res_input()),
                ..p.clone()
            };
            m = self.seg.predict_allow_empty(&emb, &again)?;
            self.decoder_seconds += m.decoder_seconds;
        }
        self.done += 1;
        if let Some(p) = self.progress {
            p.advance(self.done, Detail::Item(&scene.images[view].name));
        }
        Ok(ViewMask {
            mask: m.to_image(),
            score: m.score,
        })
    }

    /// For a lone click: SAM's mask fed back as its own `mask_input` (where the multimask pick
    /// flips between part and whole, this flips: fox's head became the wall), and the click
    /// moved by [`CLICK_JITTER`] of the image's longer side in four directions (a click near an
    /// edge or on a part boundary changes the answer). Five decoder runs, no encoder run.
    fn alternatives(
        &mut self,
        scene: &Scene,
        view: usize,
        click: &[PointPrompt],
    ) -> Result<ClickAlternatives> {
        let emb = self.embedding(scene, view)?;
        let base = sam_prompts(click, None);
        let first = self.seg.predict_allow_empty(&emb, &base)?;
        self.decoder_seconds += first.decoder_seconds;
        let mut out = ClickAlternatives::default();
        if !first.is_empty() {
            let again = Prompts {
                mask_input: Some(first.low_res_input()),
                ..base.clone()
            };
            let m = self.seg.predict_allow_empty(&emb, &again)?;
            self.decoder_seconds += m.decoder_seconds;
            out.refined = Some(m.to_image());
        }
        let (w, h) = (emb.width as f64, emb.height as f64);
        let step = (CLICK_JITTER * w.max(h)).max(2.0);
        for (dx, dy) in [(-1.0, 0.0), (1.0, 0.0), (0.0, -1.0), (0.0, 1.0)] {
            let moved: Vec<PointPrompt> = click
                .iter()
                .map(|p| PointPrompt {
                    xy: [
                        (p.xy[0] + dx * step).clamp(0.0, w - 1e-3),
                        (p.xy[1] + dy * step).clamp(0.0, h - 1e-3),
                    ],
                    positive: p.positive,
                })
                .collect();
            let m = self
                .seg
                .predict_allow_empty(&emb, &sam_prompts(&moved, None))?;
            self.decoder_seconds += m.decoder_seconds;
            out.moved.push(m.to_image());
        }
        Ok(out)
    }
}

/// How far the click moves for [`SamViews`]'s alternatives, as a fraction of the image's longer
/// side (3 px on the demo's 320 x 240): about how precisely a person clicks at full view.
pub const CLICK_JITTER: f64 = 0.01;

fn sam_prompts(prompts: &[PointPrompt], bbox: Option<[f64; 4]>) -> Prompts {
    Prompts {
        points: prompts
            .iter()
            .map(|p| Point {
                x: p.xy[0] as f32,
                y: p.xy[1] as f32,
                positive: p.positive,
            })
            .collect(),
        bbox: bbox.map(|b| [b[0] as f32, b[1] as f32, b[2] as f32, b[3] as f32]),
        mask_input: None,
    }
}
