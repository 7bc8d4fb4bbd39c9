//! The suite: which cases run, on what, perturbed how. Every case is a pure function of its
//! spec and the seed.

use super::perturb::Perturbation;
use crate::demo::Variant;
use serde::Serialize;

/// What a case runs on.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Subject {
    /// The demo scene (or a variant), scored against its exact truth.
    Demo(Variant),
    /// lego (NeRF-synthetic, triangulated by `objnerf sfm`), scored against its alpha.
    Lego,
}

/// Where a click case clicks, relative to the true mask of the clicked view.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ClickKind {
    /// Anywhere inside.
    Inside,
    /// On the mask's edge (an inside pixel next to an outside one).
    Edge,
    /// Just outside (2-4 px from the mask): not the object; reported, not scored.
    Outside,
}

/// What a case does.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "job", rename_all = "snake_case")]
pub enum Job {
    /// `extract` on these objects, each from its suggested click: segment, field, mesh.
    Extract { objects: Vec<String> },
    /// Segmentation of the mug alone from the `index`-th random click of `kind`.
    Click { kind: ClickKind, index: usize },
}

#[derive(Clone, Debug, Serialize)]
pub struct CaseSpec {
    pub id: String,
    /// Table and chart group (e.g. "pose noise (deg)") and the strength within it.
    pub group: String,
    pub strength: f64,
    pub subject: Subject,
    pub perturbation: Perturbation,
    pub job: Job,
}

fn extract(id: &str, subject: Subject, p: Perturbation, objects: &[&str]) -> CaseSpec {
    let (group, strength) = p.group();
    CaseSpec {
        id: id.to_string(),
        group: group.to_string(),
        strength,
        subject,
        perturbation: p,
        job: Job::Extract {
            objects: objects.iter().map(|s| s.to_string()).collect(),
        },
    }
}

fn clicks(kind: ClickKind, n: usize) -> impl Iterator<Item = CaseSpec> {
    (0..n).map(move |index| {
        let name = match kind {
            ClickKind::Inside => "inside",
            ClickKind::Edge => "edge",
            ClickKind::Outside => "outside",
        };
        CaseSpec {
            id: format!("click_{name}_{index:02}"),
            group: format!("click ({name})"),
            strength: index as f64,
            subject: Subject::Demo(Variant::Standard),
            perturbation: Perturbation::None,
            job: Job::Click { kind, index },
        }
    })
}

/// Clicks inside the mug's true mask in the full suite (the 50).
pub const INSIDE_CLICKS: usize = 50;
/// Clicks on its edge and just outside it.
pub const EDGE_CLICKS: usize = 10;
pub const OUTSIDE_CLICKS: usize = 10;

/// The full suite (`lego`: whether lego is there to add its cases).
pub fn full_suite(lego: bool) -> Vec<CaseSpec> {
    use Perturbation::*;
    let demo = Subject::Demo(Variant::Standard);
    let mug = ["mug"];
    let mut v = vec![extract("baseline", demo.clone(), None, &mug)];
    for n in [5, 10, 20] {
        v.push(extract(
            &format!("views_{n}"),
            demo.clone(),
            Views { count: n },
            &mug,
        ));
    }
    for d in [0.5, 1.0, 2.0] {
        v.push(extract(
            &format!("pose_{d}"),
            demo.clone(),
            PoseNoise { degrees: d },
            &mug,
        ));
    }
    for s in [0.03, 0.06, 0.12] {
        v.push(extract(
            &format!("noise_{s}"),
            demo.clone(),
            ImageNoise { sigma: s },
            &mug,
        ));
    }
    for s in [0.5, 1.0] {
        v.push(extract(
            &format!("exposure_{s}"),
            demo.clone(),
            Exposure { stops: s },
            &mug,
        ));
    }
    for px in [3.0, 7.0] {
        v.push(extract(
            &format!("blur_{px}"),
            demo.clone(),
            MotionBlur { pixels: px },
            &mug,
        ));
    }
    for (i, var) in [
        Variant::OutOfFrame,
        Variant::Occluded,
        Variant::Textureless,
        Variant::Distractor,
    ]
    .into_iter()
    .enumerate()
    {
        let mut c = extract(var.name(), Subject::Demo(var), None, &mug);
        c.group = "object".into();
        c.strength = i as f64;
        v.push(c);
    }
    for objects in [
        &["mug", "sphere"][..],
        &["mug", "sphere", "box", "torus"][..],
    ] {
        let mut c = extract(
            &format!("objects_{}", objects.len()),
            demo.clone(),
            None,
            objects,
        );
        c.group = "objects at once".into();
        c.strength = objects.len() as f64;
        v.push(c);
    }
    v.extend(clicks(ClickKind::Inside, INSIDE_CLICKS));
    v.extend(clicks(ClickKind::Edge, EDGE_CLICKS));
    v.extend(clicks(ClickKind::Outside, OUTSIDE_CLICKS));
    if lego {
        let l = ["lego"];
        v.push(extract("lego_baseline", Subject::Lego, None, &l));
        v.push(extract(
            "lego_views_25",
            Subject::Lego,
            Views { count: 25 },
            &l,
        ));
        v.push(extract(
            "lego_pose_1.0",
            Subject::Lego,
            PoseNoise { degrees: 1.0 },
            &l,
        ));
    }
    v
}

/// The quick suite: a few cases across the stages, for the test suite (no silent failure).
pub fn quick_suite() -> Vec<CaseSpec> {
    use Perturbation::*;
    let demo = Subject::Demo(Variant::Standard);
    let mug = ["mug"];
    let mut v = vec![
        extract("baseline", demo.clone(), None, &mug),
        extract("pose_2.0", demo, PoseNoise { degrees: 2.0 }, &mug),
    ];
    v.extend(clicks(ClickKind::Inside, 2));
    v.extend(clicks(ClickKind::Edge, 1));
    v
}
