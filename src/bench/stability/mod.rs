//! `objnerf bench stability`: how the pipeline behaves as the capture gets worse, and whether
//! every failure is flagged. Each case perturbs a capture with exact truth (the demo scene and
//! its variants; lego where present), runs `extract` (or the segmentation alone, for the click
//! cases) with a step budget, scores every stage against the truth ([`score`]) and classifies
//! the case from the scores and the run's own warnings:
//!
//! | | metrics above the floors | below |
//! |---|---|---|
//! | no warning | **ok** | **silent** |
//! | warning (or a clear error) | **false alarm** | **detected** |
//!
//! The aim is no silent case. [`cases`] lists the suite, [`perturb`] makes the captures,
//! [`run`] runs a case, [`report`] writes the JSON, the markdown table and the charts.

pub mod cases;
pub mod outcome;
pub mod perturb;
pub mod report;
pub mod run;
pub mod score;

use crate::error::{Error, Result};
use crate::sam::Segmenter;
use crate::util::{Detail, Progress};
use cases::Subject;
pub use outcome::{
    classify, summarise, CaseResult, StabilityOptions, StabilityReport, Summary, Verdict,
};
use run::{prepare_demo, prepare_lego, run_case, subject_dir, Prepared};
use std::collections::BTreeMap;

/// Run the suite and write its results into `opts.out` (stability.json, stability.md and the
/// charts). `command` is recorded as given; `progress` hears one step per case.
pub fn run_suite(
    opts: &StabilityOptions,
    seg: &Segmenter,
    command: &str,
    progress: &dyn Progress,
) -> Result<StabilityReport> {
    std::fs::create_dir_all(&opts.out).map_err(|e| Error::io(&opts.out, e))?;
    let machine = crate::util::machine::machine();
    let (t0, c0) = (
        std::time::Instant::now(),
        crate::util::machine::cpu_seconds(),
    );
    let mut skipped = Vec::new();
    let lego = match &opts.lego {
        Some(p) if opts.quick => {
            skipped.push(format!("lego ({}): not in the quick suite", p.display()));
            None
        }
        Some(p) => Some(p.clone()),
        None => {
            if !opts.quick {
                skipped.push("lego: no --lego model given".into());
            }
            None
        }
    };
    skipped.push(
        "fox: no truth for its object (no masks, no mesh), so its cases could not be scored".into(),
    );
    let mut specs = if opts.quick {
        cases::quick_suite()
    } else {
        cases::full_suite(lego.is_some())
    };
    if let Some(only) = &opts.only {
        specs.retain(|s| s.id.contains(only.as_str()));
    }
    let mut prepared: Vec<(Subject, Prepared)> = Vec::new();
    let mut report = StabilityReport {
        command: command.to_string(),
        machine,
        load_average_end: None,
        git_commit: crate::util::machine::git_commit(),
        quick: opts.quick,
        seed: opts.seed,
        steps: opts.steps,
        floors: BTreeMap::from([
            ("miou", score::MIOU_FLOOR),
            ("obstruction_f1", score::F1_FLOOR),
            ("psnr_db", score::PSNR_FLOOR),
            ("segment_share", score::SEGMENT_SHARE_FLOOR),
            ("field_share", score::FIELD_SHARE_FLOOR),
            ("chamfer_fraction_of_diagonal", score::CHAMFER_FLOOR),
        ]),
        skipped,
        summary: summarise(&[], 0.0, 0.0),
        cases: Vec::new(),
    };
    progress.begin("stability", specs.len() as u64);
    for (i, spec) in specs.iter().enumerate() {
        if !prepared.iter().any(|(s, _)| *s == spec.subject) {
            let dir = subject_dir(&opts.out, &spec.subject);
            let p = match &spec.subject {
                Subject::Demo(v) => prepare_demo(*v, &dir)?,
                Subject::Lego => prepare_lego(lego.as_deref().expect("lego cases need lego"))?,
            };
            prepared.push((spec.subject.clone(), p));
        }
        let prep = &prepared
            .iter()
            .find(|(s, _)| *s == spec.subject)
            .expect("prepared above")
            .1;
        report.cases.push(run_case(spec, prep, opts, seg)?);
        report.summary = summarise(
            &report.cases,
            t0.elapsed().as_secs_f64(),
            crate::util::machine::cpu_seconds() - c0,
        );
        report.load_average_end = crate::util::machine::machine().load_average;
        // Written after every case: a suite stopped part-way leaves what it measured.
        report::write_all(&report, &opts.out)?;
        progress.advance(i as u64 + 1, Detail::Item(&spec.id));
    }
    progress.end();
    Ok(report)
}
