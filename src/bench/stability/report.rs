//! The suite's outputs: `stability.json` (everything), `stability.md` (the tables the README
//! summarises) and two SVG charts: success rate against perturbation strength per stage, and
//! accuracy against time across the suite.

use super::cases::Subject;
use super::cases::{ClickKind, Job};
use super::outcome::{CaseResult, StabilityReport, Verdict};
use super::score::{ObjectScores, MIOU_FLOOR, PSNR_FLOOR};
use crate::error::{Error, Result};
use crate::util::atomic::write_bytes_atomic;
use crate::util::chart::{svg, ChartResult, Layer, Mark, Panel, RGBColor, SeriesLabelPosition};
use std::fmt::Write;
use std::ops::Range;
use std::path::Path;

pub fn write_all(r: &StabilityReport, out: &Path) -> Result<()> {
    let path = out.join("stability.json");
    let json = serde_json::to_string_pretty(r).map_err(|e| Error::json(&path, e))?;
    write_bytes_atomic(&path, json.as_bytes())?;
    write_bytes_atomic(&out.join("stability.md"), markdown(r).as_bytes())?;
    let chart_err = |p: &Path, e: String| Error::invalid(format!("{}: {e}", p.display()));
    let p = out.join("stability_success.svg");
    let svg = success_chart(&r.cases).map_err(|e| chart_err(&p, e.to_string()))?;
    write_bytes_atomic(&p, svg.as_bytes())?;
    let p = out.join("stability_accuracy_time.svg");
    let svg = accuracy_chart(&r.cases).map_err(|e| chart_err(&p, e.to_string()))?;
    write_bytes_atomic(&p, svg.as_bytes())
}

fn f(v: Option<f64>, digits: usize) -> String {
    v.map_or("-".into(), |x| format!("{x:.digits$}"))
}

fn codes(c: &CaseResult) -> String {
    let mut v: Vec<&str> = c.warnings.iter().map(|w| w.code).collect();
    v.dedup();
    if let Some(e) = &c.error {
        let short: String = e.chars().take(70).collect();
        v.push("error");
        return format!("{}: {short}", v.join(", "));
    }
    v.join(", ")
}

fn is_click(c: &CaseResult) -> Option<ClickKind> {
    match c.spec.job {
        Job::Click { kind, .. } => Some(kind),
        Job::Extract { .. } => None,
    }
}

/// The markdown tables: summary, every extract case, the clicks.
pub fn markdown(r: &StabilityReport) -> String {
    let s = &r.summary;
    let mut m = String::new();
    let _ = writeln!(
        m,
        "# Stability suite{}\n",
        if r.quick { " (quick)" } else { "" }
    );
    let _ = writeln!(
        m,
        "`{}` at commit {} on {} ({} cores), load average {} at the start and {} at the end; {:.0} s wall, {:.0} s CPU; {} training steps per object, seed {}.\n",
        r.command,
        r.git_commit.as_deref().unwrap_or("?"),
        r.machine.cpu,
        r.machine.cores,
        f(r.machine.load_average, 1),
        f(r.load_average_end, 1),
        s.seconds,
        s.cpu_seconds,
        r.steps,
        r.seed
    );
    let _ = writeln!(
        m,
        "Floors: mIoU >= {} and a good mask (IoU >= {0}) in >= {}% of the views that show the object, obstructed-view F1 >= {}, object PSNR >= {} dB (novel views, over the true mask's box) in the mean and in >= {}% of the views, Chamfer <= {}% of the true box diagonal (`docs/floors.md`). A failure counts as detected only by a warning about it (its stage, the capture, or a failed earlier stage).\n",
        r.floors["miou"],
        100.0 * r.floors["segment_share"],
        r.floors["obstruction_f1"],
        r.floors["psnr_db"],
        100.0 * r.floors["field_share"],
        100.0 * r.floors["chamfer_fraction_of_diagonal"]
    );
    let counts: Vec<String> = s.counts.iter().map(|(k, v)| format!("{k} {v}")).collect();
    let _ = writeln!(
        m,
        "**{} scored cases: {}; silent {}; false alarms {:.1}%.**\n",
        s.scored,
        counts.join(", "),
        s.silent,
        100.0 * s.false_alarm_rate
    );
    if let (Some(med), Some(p10)) = (s.click_median_miou, s.click_p10_miou) {
        let _ = writeln!(
            m,
            "Clicks inside the mug: median mIoU {med:.3}, 10th percentile {p10:.3}; {} below {} ({} of them flagged).\n",
            s.clicks_below_floor, r.floors["miou"], s.clicks_below_floor_flagged
        );
    }
    for sk in &r.skipped {
        let _ = writeln!(m, "- skipped: {sk}");
    }
    let _ = writeln!(
        m,
        "\n| case | group | strength | verdict | mIoU | bad masks | F1 | PSNR | bad views | Chamfer % | warnings | s | CPU s | MiB |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
    );
    let none = ObjectScores::default();
    for c in r.cases.iter().filter(|c| is_click(c).is_none()) {
        // A refused case has no scores: one row all the same.
        let refused = c.objects.is_empty().then_some((0, &none));
        for (i, o) in c.objects.iter().enumerate().chain(refused) {
            let _ = writeln!(
                m,
                "| {}{} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {:.0} | {:.0} | {} |",
                c.spec.id,
                if c.objects.len() > 1 {
                    format!(" ({})", o.object)
                } else {
                    String::new()
                },
                c.spec.group,
                c.spec.strength,
                if i == 0 { c.verdict.name() } else { "" },
                f(o.miou, 3),
                share(o.segment_failed_views, o.segment_views),
                f(o.obstruction_f1, 2),
                f(o.psnr, 1),
                share(o.field_failed_views, o.psnr_views.len()),
                f(o.chamfer.map(|x| 100.0 * x), 2),
                if i == 0 { codes(c) } else { String::new() },
                c.seconds,
                c.cpu_seconds,
                c.peak_rss_mib
            );
        }
    }
    let _ = writeln!(
        m,
        "\n### Clicks\n\n| case | click (px) | verdict | mIoU | F1 | warnings | s |\n|---|---|---|---|---|---|---|"
    );
    for c in r.cases.iter().filter(|c| is_click(c).is_some()) {
        let o = c.objects.first().cloned().unwrap_or_default();
        let _ = writeln!(
            m,
            "| {} | {} | {} | {} | {} | {} | {:.0} |",
            c.spec.id,
            c.click
                .map_or("-".into(), |p| format!("{:.1}, {:.1}", p[0], p[1])),
            c.verdict.name(),
            f(o.miou, 3),
            f(o.obstruction_f1, 2),
            codes(c),
            c.seconds
        );
    }
    m
}

/// Mean over a case's objects of a per-object figure.
fn mean_of(c: &CaseResult, get: impl Fn(&ObjectScores) -> Option<f64>) -> Option<f64> {
    let v: Vec<f64> = c.objects.iter().filter_map(get).collect();
    (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
}

/// One figure of an object's scores.
type Figure = fn(&ObjectScores) -> Option<f64>;

const GROUPS: [&str; 6] = [
    "views",
    "pose noise (deg)",
    "image noise (sigma)",
    "exposure (+-stops)",
    "motion blur (px)",
    "objects at once",
];

/// Success rate (share of views with a good mask; share of novel views with a good render)
/// against strength, a panel per perturbation, the unperturbed baseline at its strength.
fn success_chart(cases: &[CaseResult]) -> ChartResult<String> {
    let baseline = cases.iter().find(|c| c.spec.id == "baseline");
    let panels: Vec<Panel> = GROUPS
        .iter()
        .map(|&group| {
            // The demo's cases (lego's are in the table).
            let mut pts: Vec<(f64, &CaseResult)> = cases
                .iter()
                .filter(|c| c.spec.group == group && matches!(c.spec.subject, Subject::Demo(_)))
                .map(|c| (c.spec.strength, c))
                .collect();
            if let Some(b) = baseline {
                let s = match group {
                    "views" => 36.0,
                    "objects at once" => 1.0,
                    _ => 0.0,
                };
                pts.push((s, b));
            }
            pts.sort_by(|a, b| a.0.total_cmp(&b.0));
            let x1 = match pts.iter().map(|p| p.0).fold(0.0f64, f64::max) {
                x if x > 0.0 => x * 1.1,
                _ => 1.0,
            };
            let series: [(&str, RGBColor, Figure); 2] = [
                (
                    "segment: views with mask IoU >= floor",
                    RGBColor(0, 0, 255),
                    |o| o.segment_success,
                ),
                (
                    "field: novel views with PSNR >= floor",
                    RGBColor(255, 0, 0),
                    |o| o.field_success,
                ),
            ];
            let layers = series
                .into_iter()
                .map(|(name, colour, get)| {
                    let line = pts
                        .iter()
                        .filter_map(|(x, c)| {
                            let y = if c.error.is_some() {
                                Some(0.0)
                            } else {
                                mean_of(c, get)
                            };
                            y.map(|y| (*x, y))
                        })
                        .collect();
                    Layer::new(name, colour, line)
                })
                .collect();
            Panel {
                title: group.to_string(),
                x_label: "strength".into(),
                y_label: "success rate".into(),
                x: 0.0..x1,
                // Room above 1 for the legend.
                y: -0.02..1.35,
                layers,
                legend: SeriesLabelPosition::UpperRight,
            }
        })
        .collect();
    svg((1500, 820), 2, &panels)
}

fn verdict_colour(v: Verdict) -> RGBColor {
    match v {
        Verdict::Ok => RGBColor(40, 150, 60),
        Verdict::FalseAlarm => RGBColor(230, 160, 0),
        Verdict::Detected => RGBColor(30, 90, 200),
        Verdict::Silent => RGBColor(220, 20, 20),
        Verdict::NotScored => RGBColor(150, 150, 150),
    }
}

/// Accuracy against time: mIoU and object PSNR against each case's wall seconds, coloured by
/// verdict.
fn accuracy_chart(cases: &[CaseResult]) -> ChartResult<String> {
    let t1 = cases.iter().map(|c| c.seconds).fold(1.0f64, f64::max) * 1.1;
    let panels: [(&str, &str, Figure, Range<f64>, f64); 2] = [
        (
            "mask mIoU against case time",
            "mask mIoU",
            |o| o.miou,
            0.0..1.0,
            MIOU_FLOOR,
        ),
        (
            "object PSNR (dB) against case time",
            "object PSNR (dB)",
            |o| o.psnr,
            8.0..26.0,
            PSNR_FLOOR,
        ),
    ];
    let panels: Vec<Panel> = panels
        .into_iter()
        .map(|(title, y_label, get, y, floor)| {
            let x = 0.0..t1;
            let mut layers = vec![Layer::level(
                Some("floor"),
                RGBColor(128, 128, 128),
                floor,
                &x,
            )];
            for v in [
                Verdict::Ok,
                Verdict::FalseAlarm,
                Verdict::Detected,
                Verdict::Silent,
                Verdict::NotScored,
            ] {
                let pts: Vec<(f64, f64)> = cases
                    .iter()
                    .filter(|c| c.verdict == v)
                    .filter_map(|c| mean_of(c, get).map(|y| (c.seconds, y)))
                    .collect();
                if !pts.is_empty() {
                    layers.push(Layer::new(v.name(), verdict_colour(v), pts).mark(Mark::Points(4)));
                }
            }
            Panel {
                title: title.to_string(),
                x_label: "wall seconds (shared 2-core machine)".into(),
                y_label: y_label.into(),
                x,
                y,
                layers,
                legend: SeriesLabelPosition::LowerRight,
            }
        })
        .collect();
    svg((1400, 520), 1, &panels)
}

/// "k of n": views that fell short of how many were scored.
fn share(failed: usize, of: usize) -> String {
    if of == 0 {
        "-".into()
    } else {
        format!("{failed} of {of}")
    }
}
