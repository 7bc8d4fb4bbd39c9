//! What the suite's cases come to: the options, each case's result and verdict, the summary,
//! and the report the outputs are written from.

use super::cases::{self, CaseSpec, Job};
use super::score::{self, ObjectScores};
use crate::util::{Stage, Warning};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::PathBuf;

#[derive(Clone, Debug)]
pub struct StabilityOptions {
    /// The suite's folder: scenes, cases, and the results.
    pub out: PathBuf,
    /// The few cases of [`cases::quick_suite`] instead of the full suite.
    pub quick: bool,
    /// Seeds every perturbation and training.
    pub seed: u64,
    /// Training steps per object (a step budget: results do not depend on the machine's load).
    pub steps: usize,
    /// lego triangulated by `objnerf sfm` (a COLMAP model), to add its cases (None: skipped).
    pub lego: Option<PathBuf>,
    /// Run only the cases whose id contains this.
    pub only: Option<String>,
}

impl Default for StabilityOptions {
    fn default() -> Self {
        StabilityOptions {
            out: PathBuf::from("runs/stability"),
            quick: false,
            seed: 0,
            steps: 1000,
            lego: None,
            only: None,
        }
    }
}

/// How a case came out.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// Metrics above the floors, no warning.
    Ok,
    /// Metrics above the floors, but warned about.
    FalseAlarm,
    /// Metrics below a floor, and warned about (or refused with a clear error).
    Detected,
    /// Metrics below a floor, no warning: the failure the suite exists to rule out.
    Silent,
    /// Clicks outside the object: what happens is reported, not scored.
    NotScored,
}

impl Verdict {
    pub fn name(self) -> &'static str {
        match self {
            Verdict::Ok => "ok",
            Verdict::FalseAlarm => "false alarm",
            Verdict::Detected => "detected",
            Verdict::Silent => "SILENT",
            Verdict::NotScored => "not scored",
        }
    }
}

/// One object's verdict from its scores and the warnings about it (or about the whole scene).
/// A stage fails when its scores fall under the floors; a failure is detected only by a warning
/// about it: one from the failing stage itself or one that speaks of it ([`also_about`]), one
/// from the capture (the scene stage: poses and views every later stage stands on), or one from
/// an earlier stage that failed too (its warning is then confirmed, and what follows inherits
/// the cause). A warning about a later stage, or an unconfirmed one about an earlier stage, does
/// not count. A warning about a stage the truth cannot score (lego's mesh: there is no true
/// mesh) counts neither way.
fn object_verdict(s: &ObjectScores, warnings: &[Warning]) -> Verdict {
    let failed = |stage: Stage| match stage {
        Stage::Scene => Some(false),
        Stage::Segment => Some(s.segment_bad()),
        Stage::Field => s.field_bad(),
        Stage::Mesh => s.mesh_bad(),
    };
    let warned: Vec<Stage> = warnings
        .iter()
        .filter(|w| w.object.as_deref().is_none_or(|o| o == s.object))
        .flat_map(|w| std::iter::once(w.stage).chain(also_about(w.code).iter().copied()))
        .filter(|st| *st == Stage::Scene || failed(*st).is_some())
        .collect();
    let stages = [Stage::Segment, Stage::Field, Stage::Mesh];
    let failures: Vec<Stage> = stages
        .into_iter()
        .filter(|st| failed(*st) == Some(true))
        .collect();
    let about = |failure: Stage| {
        warned.iter().any(|w| {
            *w == failure || *w == Stage::Scene || (*w < failure && failed(*w) == Some(true))
        })
    };
    match (failures.is_empty(), warned.is_empty()) {
        (true, true) => Verdict::Ok,
        (true, false) => Verdict::FalseAlarm,
        (false, _) if failures.iter().all(|f| about(*f)) => Verdict::Detected,
        (false, _) => Verdict::Silent,
    }
}

/// The later stages a check's warning speaks of besides its own, as its message tells the user
/// (`docs/self-checks.md`): views from one side only, or too few, leave the field and the mesh
/// to make up what no view saw; floaters end up as stray pieces of the mesh.
fn also_about(code: &str) -> &'static [Stage] {
    match code {
        "one_sided_views" | "few_views_ok" => &[Stage::Field, Stage::Mesh],
        "floaters" => &[Stage::Mesh],
        _ => &[],
    }
}

/// A case's verdict: an error is a detected failure (the run refused with a message); else the
/// worst of its objects' (silent, then detected, then false alarm).
pub fn classify(scores: &[ObjectScores], warnings: &[Warning], error: bool) -> Verdict {
    if error {
        return Verdict::Detected;
    }
    let v: Vec<Verdict> = scores.iter().map(|s| object_verdict(s, warnings)).collect();
    [Verdict::Silent, Verdict::Detected, Verdict::FalseAlarm]
        .into_iter()
        .find(|x| v.contains(x))
        .unwrap_or(Verdict::Ok)
}

#[derive(Clone, Debug, Serialize)]
pub struct CaseResult {
    pub spec: CaseSpec,
    pub verdict: Verdict,
    /// The click (pixels) of a click case.
    pub click: Option<[f64; 2]>,
    pub objects: Vec<ObjectScores>,
    pub warnings: Vec<Warning>,
    /// The run's error, when it refused.
    pub error: Option<String>,
    pub seconds: f64,
    pub cpu_seconds: f64,
    pub peak_rss_mib: u64,
}

/// What the suite found, over the scored cases.
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    pub cases: usize,
    pub scored: usize,
    pub counts: BTreeMap<String, usize>,
    pub silent: usize,
    pub false_alarm_rate: f64,
    /// Over the inside clicks: median and 10th percentile of mIoU (a refused click counts 0),
    /// how many fell under the floor and whether each of those was flagged.
    pub click_median_miou: Option<f64>,
    pub click_p10_miou: Option<f64>,
    pub clicks_below_floor: usize,
    pub clicks_below_floor_flagged: usize,
    pub seconds: f64,
    pub cpu_seconds: f64,
}

pub fn summarise(results: &[CaseResult], seconds: f64, cpu_seconds: f64) -> Summary {
    let scored: Vec<&CaseResult> = results
        .iter()
        .filter(|r| r.verdict != Verdict::NotScored)
        .collect();
    let mut counts = BTreeMap::new();
    for r in &scored {
        *counts.entry(r.verdict.name().to_string()).or_insert(0) += 1;
    }
    let count = |v: Verdict| scored.iter().filter(|r| r.verdict == v).count();
    let inside: Vec<&CaseResult> = results
        .iter()
        .filter(|r| {
            matches!(
                r.spec.job,
                Job::Click {
                    kind: cases::ClickKind::Inside,
                    ..
                }
            )
        })
        .collect();
    let mious: Vec<f64> = inside
        .iter()
        .map(|r| r.objects.first().and_then(|o| o.miou).unwrap_or(0.0))
        .collect();
    let below: Vec<&&CaseResult> = inside
        .iter()
        .filter(|r| r.objects.first().and_then(|o| o.miou).unwrap_or(0.0) < score::MIOU_FLOOR)
        .collect();
    Summary {
        cases: results.len(),
        scored: scored.len(),
        counts,
        silent: count(Verdict::Silent),
        false_alarm_rate: count(Verdict::FalseAlarm) as f64 / scored.len().max(1) as f64,
        click_median_miou: crate::util::stats::median(mious.clone()),
        click_p10_miou: crate::util::stats::quantile(mious, 0.1),
        clicks_below_floor: below.len(),
        clicks_below_floor_flagged: below
            .iter()
            .filter(|r| r.verdict == Verdict::Detected)
            .count(),
        seconds,
        cpu_seconds,
    }
}

/// Everything the suite wrote about itself.
#[derive(Clone, Debug, Serialize)]
pub struct StabilityReport {
    pub command: String,
    pub machine: crate::util::machine::Machine,
    pub load_average_end: Option<f64>,
    pub git_commit: Option<String>,
    pub quick: bool,
    pub seed: u64,
    pub steps: usize,
    pub floors: BTreeMap<&'static str, f64>,
    /// Subjects the suite left out, and why.
    pub skipped: Vec<String>,
    pub summary: Summary,
    pub cases: Vec<CaseResult>,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn good() -> ObjectScores {
        ObjectScores {
            object: "mug".into(),
            miou: Some(0.94),
            segment_success: Some(1.0),
            obstruction_f1: Some(1.0),
            psnr: Some(20.0),
            field_success: Some(1.0),
            chamfer: Some(0.015),
            ..Default::default()
        }
    }

    fn warn(stage: Stage) -> Warning {
        Warning::new(stage, "w", 0.0, 0.0, "").about("mug")
    }

    #[test]
    fn a_failure_is_detected_only_by_a_warning_about_it() {
        let ok = good();
        assert_eq!(object_verdict(&ok, &[]), Verdict::Ok);
        assert_eq!(
            object_verdict(&ok, &[warn(Stage::Mesh)]),
            Verdict::FalseAlarm
        );
        // A field under the floor: its own warning or the capture's detects it; a mesh warning
        // or an unconfirmed one about the masks (which are good) does not.
        let blurred = ObjectScores {
            psnr: Some(16.0),
            ..good()
        };
        assert_eq!(
            object_verdict(&blurred, &[warn(Stage::Field)]),
            Verdict::Detected
        );
        assert_eq!(
            object_verdict(&blurred, &[warn(Stage::Scene)]),
            Verdict::Detected
        );
        assert_eq!(
            object_verdict(&blurred, &[warn(Stage::Mesh)]),
            Verdict::Silent
        );
        assert_eq!(
            object_verdict(&blurred, &[warn(Stage::Segment)]),
            Verdict::Silent
        );
        // Bad masks, and the field they taught: the masks' warning covers both.
        let spilled = ObjectScores {
            miou: Some(0.5),
            psnr: Some(10.0),
            ..good()
        };
        assert_eq!(
            object_verdict(&spilled, &[warn(Stage::Segment)]),
            Verdict::Detected
        );
        assert_eq!(
            object_verdict(&spilled, &[warn(Stage::Field)]),
            Verdict::Silent
        );
        // A wrong back of the mesh, told by the views' coverage.
        let unseen_back = ObjectScores {
            chamfer: Some(0.05),
            ..good()
        };
        let mut one_sided = warn(Stage::Segment);
        one_sided.code = "one_sided_views";
        assert_eq!(
            object_verdict(&unseen_back, &[one_sided]),
            Verdict::Detected
        );
        assert_eq!(
            object_verdict(&unseen_back, &[warn(Stage::Segment)]),
            Verdict::Silent
        );
    }

    #[test]
    fn too_many_bad_views_fail_a_good_mean() {
        let patchy = ObjectScores {
            segment_success: Some(0.7),
            ..good()
        };
        assert_eq!(object_verdict(&patchy, &[]), Verdict::Silent);
        let two_of_six = ObjectScores {
            field_success: Some(4.0 / 6.0),
            ..good()
        };
        assert_eq!(object_verdict(&two_of_six, &[]), Verdict::Silent);
        let one_of_six = ObjectScores {
            field_success: Some(5.0 / 6.0),
            ..good()
        };
        assert_eq!(object_verdict(&one_of_six, &[]), Verdict::Ok);
    }
}
