//! The types multi-view segmentation shares between its parts: prompts, a segmenter's answer,
//! per-view results, and the options of the propagation.

use super::hull::HullOptions;
use super::regions::CleanOptions;
use crate::error::Result;
use crate::scene::Scene;
use image::GrayImage;
use serde::Serialize;

/// A point prompt in pixel coordinates (corner origin), positive or negative.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct PointPrompt {
    pub xy: [f64; 2],
    pub positive: bool,
}

/// What the propagation needs from a segmenter: a mask for a view from prompts.
pub trait ViewSegmenter {
    fn segment(
        &mut self,
        scene: &Scene,
        view: usize,
        prompts: &[PointPrompt],
        bbox: Option<[f64; 4]>,
    ) -> Result<ViewMask>;

    /// Other masks the segmenter could as well have given for a lone click in `view`, to tell
    /// whether the click is ambiguous. None by default.
    fn alternatives(
        &mut self,
        _scene: &Scene,
        _view: usize,
        _click: &[PointPrompt],
    ) -> Result<ClickAlternatives> {
        Ok(ClickAlternatives::default())
    }
}

/// A segmenter's other answers to one click: its own answer refined (fed back as a prompt:
/// where the choice between part and whole is close, it flips) and the click moved a little
/// in several directions.
#[derive(Clone, Debug, Default)]
pub struct ClickAlternatives {
    pub refined: Option<GrayImage>,
    pub moved: Vec<GrayImage>,
}

/// A segmenter's answer: the mask at image size (0/255) and the model's score. (No logits: at
/// full size they are 8 MB a view, and overlaps are settled by depth.)
#[derive(Clone)]
pub struct ViewMask {
    pub mask: GrayImage,
    pub score: f32,
}

#[derive(Clone, Debug)]
pub struct PropagationOptions {
    /// Positive prompts per view after thinning (farthest-point sampling).
    pub max_prompts: usize,
    /// Negative prompts per view, from points known to lie outside the object.
    pub max_negatives: usize,
    /// Also prompt with the box around the view's features of D, grown by this fraction of its
    /// size: points alone let SAM pick one part of a many-part object (lego's bricks).
    pub box_padding: Option<f64>,
    /// Features closer than this to a mask's edge do not vote.
    pub edge_margin_px: f64,
    /// The mask covering less than this fraction of the expected mask marks a view obstructed.
    /// (IoU(mask, expected), the paper's test, mixes coverage with the expected mask's own
    /// shrinkage: on the demo scene coverage separates visible < 0.5 from the rest better.)
    pub obstruction_coverage: f64,
    /// A view needs at least this many positive features to be prompted at all.
    pub min_prompts: usize,
    /// Masks smaller than this fraction of the image are flagged tiny.
    pub tiny_fraction: f64,
    /// A view with fewer than `max_prompts` correspondences is also prompted with D's points
    /// projected into it, where its own features do not contradict them (see
    /// [`super::view_prompts`]).
    pub projected_fill: bool,
    /// How near (fraction of the image's larger side) a feature must be to contradict a
    /// projected point.
    pub free_space_radius: f64,
    /// ... and at what relative depth difference.
    pub free_space_depth: f64,
    /// Clean every mask before it votes: stray islands and pin-holes (None: SAM's mask as is).
    pub clean: Option<CleanOptions>,
    pub hull: HullOptions,
    /// Points of D farther from its median than this many times D's median distance to it
    /// leave D (a mismatched track far off in space; see `propagate::membership`). None keeps
    /// them.
    pub max_spread: Option<f64>,
}

impl Default for PropagationOptions {
    fn default() -> Self {
        PropagationOptions {
            max_prompts: 8,
            max_negatives: 3,
            box_padding: Some(0.1),
            edge_margin_px: 3.0,
            obstruction_coverage: 0.52,
            min_prompts: 1,
            tiny_fraction: 1e-3,
            projected_fill: true,
            free_space_radius: 0.02,
            free_space_depth: 0.05,
            clean: Some(CleanOptions::default()),
            hull: HullOptions::default(),
            max_spread: Some(4.0),
        }
    }
}

/// The user's prompt for one object: clicks (and optionally a box) in one view.
#[derive(Clone, Debug)]
pub struct ObjectPrompt {
    pub name: String,
    pub view: usize,
    pub points: Vec<PointPrompt>,
    pub bbox: Option<[f64; 4]>,
}

impl ObjectPrompt {
    /// One positive click at `xy` (pixels) in the view `view` names (as `Scene::find_image`).
    pub fn click(scene: &Scene, name: &str, view: &str, xy: [f64; 2]) -> Result<ObjectPrompt> {
        Ok(ObjectPrompt {
            name: name.to_string(),
            view: scene.find_image(view)?,
            points: vec![PointPrompt { xy, positive: true }],
            bbox: None,
        })
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ViewStatus {
    Ok,
    Obstructed,
    Absent,
}

#[derive(Clone, Debug, Serialize)]
pub struct ViewResult {
    pub view: String,
    pub status: ViewStatus,
    pub score: f32,
    pub expected_iou: Option<f64>,
    /// The fraction of the expected mask the mask covers: about the visible fraction of the object.
    pub expected_coverage: Option<f64>,
    pub num_prompts: usize,
    /// Of the positives, how many are D's points projected into the view (not correspondences).
    pub num_projected: usize,
    /// Position in the visiting order (0 = the clicked view), None when never prompted.
    pub order: Option<usize>,
    /// Of the tracked features well inside the mask, the fraction whose 3D points other views
    /// saw outside the object: the mask spilled onto something else (None: too few features
    /// inside to say, see `segment::checks`).
    pub spill: Option<f64>,
    /// Tracked features well outside the mask whose 3D points at least as many views saw inside
    /// the object as outside, per tracked feature well inside: the mask fell short of the
    /// object (None: too few features inside to say). The other side of a disagreement that
    /// `spill` sees from the mask that took more.
    pub shortfall: Option<f64>,
    /// "cut" (the object runs off the frame), "tiny" (mask under `tiny_fraction` of the image).
    pub flags: Vec<&'static str>,
    #[serde(skip)]
    pub mask: Option<GrayImage>,
    /// The prompts given to SAM in this view (pixels, corner origin): what to look at when a
    /// mask is wrong.
    pub prompts: Vec<PointPrompt>,
}

impl ViewResult {
    /// A view not (yet) segmented: absent until a mask says otherwise.
    pub fn unsegmented(name: &str) -> Self {
        ViewResult {
            view: name.to_string(),
            status: ViewStatus::Absent,
            score: 0.0,
            expected_iou: None,
            expected_coverage: None,
            num_prompts: 0,
            num_projected: 0,
            order: None,
            spill: None,
            shortfall: None,
            flags: vec![],
            mask: None,
            prompts: vec![],
        }
    }
}

#[derive(Clone, Debug)]
pub struct ObjectSegmentation {
    pub name: String,
    pub views: Vec<ViewResult>,
    /// D: indices into `scene.points` of the object's points.
    pub points: Vec<usize>,
    /// How far the segmenter's alternatives for the click agree with its mask (see
    /// `propagate::click_agreement`; None: no alternatives, e.g. several clicks or a box).
    pub click_agreement: Option<f64>,
}

#[derive(Clone, Copy, Default)]
pub struct Votes {
    pub inside: u32,
    pub outside: u32,
}

impl Votes {
    /// Known to lie outside: voted out, never in.
    pub fn is_outside(&self) -> bool {
        self.outside > 0 && self.inside == 0
    }
}
