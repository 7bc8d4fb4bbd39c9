//! `RUN/report.html`: what an extract run shows a person. One page beside `report.json` that
//! opens offline from the file system: the scores and every self-check in tables, each object's
//! mesh in an interactive glTF viewer, its turntable and its segmentation contact sheet.
//!
//! The viewer is model-viewer (`assets/model-viewer/`, Apache-2.0), written beside the page as
//! `RUN/viewer/`. A page opened from `file://` may run a classic `<script src>` but not an ES
//! module from a file, and may not `fetch` a `file://` URL, so the viewer is the classic-script
//! build and each `mesh.glb` is carried in the page as a `data:` URL; images are relative links.

use super::extract_report::{ExtractReport, ObjectReport};
use crate::error::{Error, Result};
use crate::util::atomic::write_bytes_atomic;
use crate::util::write_atomic;
use std::fmt::Write as _;
use std::path::Path;

const VIEWER_JS: &[u8] = include_bytes!("../../assets/model-viewer/model-viewer-umd.min.js");
const VIEWER_LICENSE: &[u8] = include_bytes!("../../assets/model-viewer/LICENSE");
/// Where the page finds the viewer, relative to the run folder.
pub const VIEWER_SCRIPT: &str = "viewer/model-viewer-umd.min.js";

/// Write `run/report.html` and the viewer beside it (`run/viewer/`), reading each object's
/// `mesh.glb` from `run`.
pub fn write_report_html(run: &Path, report: &ExtractReport) -> Result<()> {
    write_bytes_atomic(&run.join(VIEWER_SCRIPT), VIEWER_JS)?;
    write_bytes_atomic(&run.join("viewer/LICENSE"), VIEWER_LICENSE)?;
    let mut sections = String::new();
    for (i, o) in report.objects.iter().enumerate() {
        let glb_path = run.join(&o.name).join("mesh.glb");
        let glb = std::fs::read(&glb_path).map_err(|e| Error::io(&glb_path, e))?;
        sections += &object_section(i, o, &glb);
    }
    let page = format!(
        "<!doctype html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <title>objnerf extract: {title}</title>\n<script src=\"{VIEWER_SCRIPT}\"></script>\n\
         <style>{STYLE}</style>\n</head>\n<body>\n<h1>objnerf extract</h1>\n{summary}\
         <h2>Scores</h2>\n{scores}<h2>Warnings</h2>\n{warnings}{truth}{sections}</body>\n</html>\n",
        title = esc(&report.scene.display().to_string()),
        summary = summary(report),
        scores = scores_table(report),
        warnings = warnings_table(report),
        truth = truth_table(report.truth.as_ref()),
    );
    let path = run.join("report.html");
    write_atomic(&path, |w| w.write_all(page.as_bytes()))
}

const STYLE: &str = "body{font-family:sans-serif;margin:1em 2em;color:#222;background:#fff}\
table{border-collapse:collapse;margin:.5em 0}th,td{border:1px solid #bbb;padding:.2em .5em;\
text-align:left}td.n{text-align:right}.row{display:flex;flex-wrap:wrap;gap:1em;\
align-items:flex-start}model-viewer{width:480px;height:360px;background:#fff;\
border:1px solid #bbb}figure{margin:0}img{max-width:100%}";

/// The run as a whole: scene, stage times, memory and the files for every object.
fn summary(r: &ExtractReport) -> String {
    let s = &r.seconds;
    format!(
        "<p>Scene <code>{}</code>: {} object(s) in {:.0} s (segment {:.0} s, train {:.0} s, \
         mesh {:.1} s, render {:.0} s); peak memory {} MiB. Every object in one file: \
         <a href=\"mesh.glb\">mesh.glb</a>; all figures: <a href=\"report.json\">report.json</a>.</p>\n",
        esc(&r.scene.display().to_string()),
        r.objects.len(),
        s.total,
        s.segment,
        s.train,
        s.mesh,
        s.render,
        r.peak_rss_mib
    )
}

/// One row per object: segmentation, training, checks, mesh and turntable.
fn scores_table(r: &ExtractReport) -> String {
    let mut t = String::from(
        "<table>\n<tr><th>object</th><th>views ok / obstructed / absent</th>\
         <th>held-out check PSNR (dB)</th><th>training views PSNR (dB)</th>\
         <th>training PSNR (dB)</th><th>steps</th><th>train / mesh / render (s)</th>\
         <th>mesh.glb triangles (full mesh)</th><th>texture</th><th>turntable orbit</th></tr>\n",
    );
    let db = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.2}"));
    for (i, o) in r.objects.iter().enumerate() {
        let s = &o.segmentation;
        let texture = o
            .export
            .atlas
            .as_ref()
            .map_or("vertex colours".to_string(), |a| {
                format!("{0}x{0} px", a.size)
            });
        let orbit = &o.turntable;
        let _ = writeln!(
            t,
            "<tr><td><a href=\"#object-{i}\">{name}</a></td><td class=\"n\">{} / {} / {}</td>\
             <td class=\"n\">{}</td><td class=\"n\">{}</td><td class=\"n\">{:.2}</td>\
             <td class=\"n\">{}</td><td class=\"n\">{:.0} / {:.1} / {:.0}</td>\
             <td class=\"n\">{} ({})</td><td>{texture}</td>\
             <td>elevation {:.0}&deg;, from {:.0}&deg; over {:.0}&deg;</td></tr>",
            s.num_ok,
            s.num_obstructed,
            s.num_absent,
            db(o.held_out_check.psnr),
            db(o.held_out_check.train_psnr),
            o.train.run.final_psnr,
            o.train.run.steps,
            o.train_seconds,
            o.mesh_seconds,
            o.render_seconds,
            o.export.triangles,
            o.mesh.triangles,
            orbit.elevation_deg,
            orbit.start_deg,
            orbit.arc_deg,
            name = esc(&o.name),
        );
    }
    t + "</table>\n"
}

/// Every self-check that tripped, or a line saying none did.
fn warnings_table(r: &ExtractReport) -> String {
    if r.warnings.is_empty() {
        return "<p>No self-check tripped.</p>\n".to_string();
    }
    let mut t = String::from(
        "<table>\n<tr><th>stage</th><th>object</th><th>check</th><th>what it means</th>\
         <th>figure</th><th>threshold</th></tr>\n",
    );
    for w in &r.warnings {
        let _ = writeln!(
            t,
            "<tr><td>{}</td><td>{}</td><td><code>{}</code></td><td>{}</td>\
             <td class=\"n\">{}</td><td class=\"n\">{}</td></tr>",
            w.stage.name(),
            esc(w.object.as_deref().unwrap_or("")),
            esc(w.code),
            esc(&w.message),
            w.figure,
            w.threshold
        );
    }
    t + "</table>\n"
}

/// The scores against the truth that callers which know it add (the demo), if any.
fn truth_table(truth: Option<&serde_json::Value>) -> String {
    let Some(serde_json::Value::Object(fields)) = truth else {
        return String::new();
    };
    let mut t = String::from("<h2>Against the truth</h2>\n<table>\n");
    for (k, v) in fields {
        let v = match v {
            serde_json::Value::String(s) => esc(s),
            serde_json::Value::Number(n) if !(n.is_u64() || n.is_i64()) => {
                format!("{:.4}", n.as_f64().unwrap_or(f64::NAN))
            }
            v => esc(&v.to_string()),
        };
        let _ = writeln!(t, "<tr><th>{}</th><td class=\"n\">{v}</td></tr>", esc(k));
    }
    t + "</table>\n"
}

/// One object: its mesh in the viewer, its turntable, its contact sheet and its files.
fn object_section(i: usize, o: &ObjectReport, glb: &[u8]) -> String {
    let name = esc(&o.name);
    let dir = url_segment(&o.name);
    let sheet = url_segment(&format!("contact_sheet_{}.png", o.name));
    format!(
        "<section id=\"object-{i}\">\n<h2>{name}</h2>\n<div class=\"row\">\n\
         <model-viewer id=\"viewer-{i}\" src=\"data:model/gltf-binary;base64,{data}\" \
         alt=\"{name}: mesh.glb\" camera-controls loading=\"eager\" interaction-prompt=\"none\" \
         shadow-intensity=\"0\"><div slot=\"progress-bar\"></div></model-viewer>\n\
         <figure><img src=\"{dir}/turntable.gif\" alt=\"{name}: turntable\">\
         <figcaption>turntable.gif (the field rendered)</figcaption></figure>\n</div>\n\
         <p>Files: <a href=\"{dir}/mesh.glb\">mesh.glb</a> (drawn above; drag to turn), \
         <a href=\"{dir}/mesh.ply\">mesh.ply</a>, <a href=\"{dir}/model.objf\">model.objf</a>.</p>\n\
         <figure><img src=\"segment/{sheet}\" alt=\"{name}: segmentation contact sheet\">\
         <figcaption>segmentation contact sheet ({ok} ok of {views} views)</figcaption></figure>\n\
         </section>\n",
        data = base64(glb),
        ok = o.segmentation.num_ok,
        views = o.segmentation.num_views,
    )
}

/// `s` safe as HTML text and as a quoted attribute value.
pub fn esc(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// `s` as one path segment of a relative URL: every byte but the unreserved ones
/// percent-encoded (so `/`, `?` and `#` in a name cannot change where a link points).
fn url_segment(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for b in s.bytes() {
        if b.is_ascii_alphanumeric() || b"-._~".contains(&b) {
            out.push(b as char);
        } else {
            let _ = write!(out, "%{b:02X}");
        }
    }
    out
}

/// Standard base64 with padding (RFC 4648), for the meshes' `data:` URLs.
fn base64(bytes: &[u8]) -> String {
    const ABC: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (b[0] as u32) << 16 | (b[1] as u32) << 8 | b[2] as u32;
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(ABC[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_rfc_4648_vectors() {
        for (plain, coded) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(plain.as_bytes()), coded, "{plain}");
        }
    }

    #[test]
    fn names_cannot_break_out_of_text_attributes_or_links() {
        assert_eq!(
            esc("<b a=\"x\" c='y'>&"),
            "&lt;b a=&quot;x&quot; c=&#39;y&#39;&gt;&amp;"
        );
        assert_eq!(url_segment("a b/../c?#é"), "a%20b%2F..%2Fc%3F%23%C3%A9");
    }
}
