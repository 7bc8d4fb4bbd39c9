//! `objnerf edit-template RUN`: an edit file for an `extract` run with every object in place.

use super::file::{Background, EditFile, EditObject};
use crate::error::{Error, Result};
use std::path::{Path, PathBuf};

/// The background of a template: a model, or a colour (`#RRGGBB`).
#[derive(Clone, Debug, PartialEq)]
pub enum TemplateBackground {
    Model(PathBuf),
    Color([f32; 3]),
}

/// A removal field in the run (`objnerf remove ... --out RUN/...` writes `background.objf`):
/// `RUN/background.objf` or `RUN/*/background.objf`, the first by name.
pub fn find_removal_field(run: &Path) -> Option<PathBuf> {
    let top = run.join("background.objf");
    if top.is_file() {
        return Some(top);
    }
    let mut subs: Vec<PathBuf> = std::fs::read_dir(run)
        .ok()?
        .flatten()
        .map(|e| e.path().join("background.objf"))
        .filter(|p| p.is_file())
        .collect();
    subs.sort();
    subs.into_iter().next()
}

/// A path as the edit file at `edit` should write it: relative to its folder where possible.
fn relative_to(edit: &Path, target: &Path) -> String {
    let base = edit.parent().unwrap_or(Path::new("."));
    crate::util::paths::relative_to(target, base)
        .to_string_lossy()
        .to_string()
}

/// The edit file `out` for the `extract` run in `run`: each object of its report.json in place
/// (`RUN/<object>/model.objf`), over `background` (None: a removal field found in the run, else
/// white).
pub fn edit_template(
    run: &Path,
    background: Option<TemplateBackground>,
    out: &Path,
) -> Result<EditFile> {
    let report_path = run.join("report.json");
    let bytes = std::fs::read(&report_path).map_err(|e| Error::io(&report_path, e))?;
    let report: serde_json::Value = crate::scene::formats::json::parse_json(&report_path, &bytes)?;
    let names: Vec<String> = report
        .get("objects")
        .and_then(|o| o.as_array())
        .map(|a| {
            a.iter()
                .filter_map(|o| o.get("name")?.as_str().map(str::to_string))
                .collect()
        })
        .unwrap_or_default();
    if names.is_empty() {
        return Err(Error::format(
            &report_path,
            "objects: no objects listed (is this an `objnerf extract` run?)",
        ));
    }
    let mut objects = Vec::new();
    for name in &names {
        let model = run.join(name).join("model.objf");
        if !model.is_file() {
            return Err(Error::format(
                &report_path,
                format!("object '{name}': its model {} is missing", model.display()),
            ));
        }
        objects.push(EditObject::in_place(name, &relative_to(out, &model), model));
    }
    let background =
        match background.or_else(|| find_removal_field(run).map(TemplateBackground::Model)) {
            Some(TemplateBackground::Model(p)) => {
                if !p.is_file() {
                    return Err(Error::invalid(format!(
                        "--background {}: no such model file",
                        p.display()
                    )));
                }
                Background::Model {
                    given: relative_to(out, &p),
                    path: p,
                }
            }
            Some(TemplateBackground::Color(c)) => Background::Color(c),
            None => Background::Color([1.0; 3]),
        };
    Ok(EditFile {
        path: out.to_path_buf(),
        metres_per_unit: 1.0,
        background,
        objects,
    })
}
