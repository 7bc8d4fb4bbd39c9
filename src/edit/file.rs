//! The edit file (`edit.json`, version 1; `docs/edit-format.md`): read from bytes with every key
//! checked (unknown keys and versions are errors; each error names the file and the field, e.g.
//! `edit.json: objects[1].scale: 0 is not a positive number`), and written back.

use super::recolour::{hex_colour, parse_hex_colour, Recolour};
use crate::error::{Error, Result};
use crate::util::write_atomic;
use glam::{DQuat, DVec3};
use serde_json::{json, Map, Value};
use std::path::{Path, PathBuf};

pub const EDIT_VERSION: u64 = 1;

/// What the objects stand on.
#[derive(Clone, Debug, PartialEq)]
pub enum Background {
    /// A scene or removal field (`.objf`), as written in the file and resolved against its folder.
    Model { given: String, path: PathBuf },
    /// A plain colour, sRGB 0..1.
    Color([f32; 3]),
}

/// One object of the edit: a field drawn under a transform.
#[derive(Clone, Debug, PartialEq)]
pub struct EditObject {
    pub name: String,
    /// The model path as written, and resolved against the edit file's folder.
    pub model_given: String,
    pub model: PathBuf,
    pub visible: bool,
    /// The model capture's unit length in metres (None: the file's).
    pub metres_per_unit: Option<f64>,
    /// In the model's own frame (None: the centre of the model's box).
    pub pivot: Option<DVec3>,
    pub translation: DVec3,
    /// Unit quaternion.
    pub rotation: DQuat,
    pub scale: f64,
    pub recolour: Option<Recolour>,
}

/// An edit file.
#[derive(Clone, Debug, PartialEq)]
pub struct EditFile {
    /// The file it was read from (or will be written to); model paths are relative to its folder.
    pub path: PathBuf,
    pub metres_per_unit: f64,
    pub background: Background,
    pub objects: Vec<EditObject>,
}

type Fields<'a> = &'a Map<String, Value>;

/// The keys of one JSON object, checked against the known ones; `at` names it ("objects[2]").
fn object<'a>(v: &'a Value, at: &str, known: &[&str]) -> std::result::Result<Fields<'a>, String> {
    let m = v
        .as_object()
        .ok_or_else(|| format!("{at}: expected an object"))?;
    if let Some(k) = m.keys().find(|k| !known.contains(&k.as_str())) {
        return Err(format!(
            "{}: unknown key '{k}' (known: {})",
            join(at, k),
            known.join(", ")
        ));
    }
    Ok(m)
}

fn join(at: &str, key: &str) -> String {
    if at.is_empty() {
        key.to_string()
    } else {
        format!("{at}.{key}")
    }
}

fn number(m: Fields, at: &str, key: &str) -> std::result::Result<Option<f64>, String> {
    match m.get(key) {
        None => Ok(None),
        Some(v) => v
            .as_f64()
            .filter(|x| x.is_finite())
            .map(Some)
            .ok_or_else(|| format!("{}: {v} is not a finite number", join(at, key))),
    }
}

fn positive(m: Fields, at: &str, key: &str) -> std::result::Result<Option<f64>, String> {
    match number(m, at, key)? {
        Some(x) if x <= 0.0 => Err(format!("{}: {x} is not a positive number", join(at, key))),
        x => Ok(x),
    }
}

fn string<'a>(m: Fields<'a>, at: &str, key: &str) -> std::result::Result<&'a str, String> {
    let v = m
        .get(key)
        .ok_or_else(|| format!("{}: missing", join(at, key)))?;
    v.as_str()
        .filter(|s| !s.is_empty())
        .ok_or_else(|| format!("{}: {v} is not a non-empty string", join(at, key)))
}

fn vec3(m: Fields, at: &str, key: &str) -> std::result::Result<Option<DVec3>, String> {
    let Some(v) = m.get(key) else { return Ok(None) };
    let bad = || format!("{}: {v} is not a list of 3 finite numbers", join(at, key));
    let a = v.as_array().filter(|a| a.len() == 3).ok_or_else(bad)?;
    let xs: Vec<f64> = a.iter().filter_map(Value::as_f64).collect();
    if xs.len() != 3 || xs.iter().any(|x| !x.is_finite()) {
        return Err(bad());
    }
    Ok(Some(DVec3::new(xs[0], xs[1], xs[2])))
}

fn rotation(m: Fields, at: &str) -> std::result::Result<DQuat, String> {
    let Some(v) = m.get("rotation") else {
        return Ok(DQuat::IDENTITY);
    };
    let at = join(at, "rotation");
    let q = object(v, &at, &["w", "x", "y", "z"])?;
    let c = |k: &str| -> std::result::Result<f64, String> {
        number(q, &at, k)?.ok_or_else(|| format!("{at}.{k}: missing"))
    };
    let quat = DQuat::from_xyzw(c("x")?, c("y")?, c("z")?, c("w")?);
    let n = quat.length();
    if n.is_nan() || n <= 1e-12 {
        return Err(format!("{at}: a zero quaternion is not a rotation"));
    }
    Ok(quat / n)
}

fn recolour(m: Fields, at: &str) -> std::result::Result<Option<Recolour>, String> {
    let Some(v) = m.get("recolour") else {
        return Ok(None);
    };
    let at = join(at, "recolour");
    let r = object(v, &at, &["target", "hue_degrees", "strength"])?;
    let strength = number(r, &at, "strength")?.unwrap_or(1.0);
    if !(0.0..=1.0).contains(&strength) {
        return Err(format!("{at}.strength: {strength} is not between 0 and 1"));
    }
    let strength = strength as f32;
    match (r.get("target"), number(r, &at, "hue_degrees")?) {
        (Some(_), Some(_)) => Err(format!(
            "{at}: give either 'target' or 'hue_degrees', not both"
        )),
        (Some(_), None) => {
            let rgb = parse_hex_colour(string(r, &at, "target")?)
                .map_err(|e| format!("{at}.target: {e}"))?;
            Ok(Some(Recolour::Target { rgb, strength }))
        }
        (None, Some(d)) => Ok(Some(Recolour::Hue {
            degrees: d as f32,
            strength,
        })),
        (None, None) => Err(format!("{at}: needs 'target' (#RRGGBB) or 'hue_degrees'")),
    }
}

fn resolve(dir: &Path, given: &str) -> PathBuf {
    let p = Path::new(given);
    if p.is_absolute() {
        p.to_path_buf()
    } else {
        dir.join(p)
    }
}

const OBJECT_KEYS: [&str; 10] = [
    "name",
    "model",
    "visible",
    "metres_per_unit",
    "pivot",
    "translation",
    "rotation",
    "scale",
    "recolour",
    // Free text for people and tools; ignored.
    "comment",
];

fn edit_object(v: &Value, at: &str, dir: &Path) -> std::result::Result<EditObject, String> {
    let m = object(v, at, &OBJECT_KEYS)?;
    let model_given = string(m, at, "model")?.to_string();
    let visible = match m.get("visible") {
        None => true,
        Some(Value::Bool(b)) => *b,
        Some(v) => return Err(format!("{at}.visible: {v} is not true or false")),
    };
    Ok(EditObject {
        name: string(m, at, "name")?.to_string(),
        model: resolve(dir, &model_given),
        model_given,
        visible,
        metres_per_unit: positive(m, at, "metres_per_unit")?,
        pivot: vec3(m, at, "pivot")?,
        translation: vec3(m, at, "translation")?.unwrap_or(DVec3::ZERO),
        rotation: rotation(m, at)?,
        scale: positive(m, at, "scale")?.unwrap_or(1.0),
        recolour: recolour(m, at)?,
    })
}

fn background(v: Option<&Value>, dir: &Path) -> std::result::Result<Background, String> {
    let v = v.ok_or("background: missing (a {\"model\": PATH} or a {\"color\": \"#RRGGBB\"})")?;
    let m = object(v, "background", &["model", "color"])?;
    match (m.contains_key("model"), m.contains_key("color")) {
        (true, false) => {
            let given = string(m, "background", "model")?.to_string();
            Ok(Background::Model {
                path: resolve(dir, &given),
                given,
            })
        }
        (false, true) => Ok(Background::Color(
            parse_hex_colour(string(m, "background", "color")?)
                .map_err(|e| format!("background.color: {e}"))?,
        )),
        _ => Err("background: give exactly one of 'model' and 'color'".into()),
    }
}

impl EditFile {
    /// Read an edit file.
    pub fn read(path: &Path) -> Result<EditFile> {
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        Self::parse(path, &bytes)
    }

    /// Parse an edit file's bytes; `path` names it in errors and anchors relative model paths.
    pub fn parse(path: &Path, bytes: &[u8]) -> Result<EditFile> {
        let v: Value = crate::scene::formats::json::parse_json(path, bytes)?;
        Self::from_value(path, &v).map_err(|m| Error::format(path, m))
    }

    fn from_value(path: &Path, v: &Value) -> std::result::Result<EditFile, String> {
        let dir = path.parent().unwrap_or(Path::new("."));
        let m = object(
            v,
            "",
            &[
                "version",
                "metres_per_unit",
                "background",
                "objects",
                "comment",
            ],
        )?;
        match m.get("version") {
            None => return Err("version: missing (this reader knows version 1)".into()),
            Some(v) if v.as_u64() == Some(EDIT_VERSION) => {}
            Some(v) => {
                return Err(format!(
                    "version: {v} is not a version this reader knows (1)"
                ))
            }
        }
        let metres_per_unit = positive(m, "", "metres_per_unit")?.unwrap_or(1.0);
        let background = background(m.get("background"), dir)?;
        let list = m
            .get("objects")
            .ok_or("objects: missing (a list, may be empty)")?
            .as_array()
            .ok_or("objects: expected a list")?;
        let mut objects = Vec::with_capacity(list.len());
        for (i, o) in list.iter().enumerate() {
            let at = format!("objects[{i}]");
            let obj = edit_object(o, &at, dir)?;
            if let Some(j) = objects.iter().position(|p: &EditObject| p.name == obj.name) {
                return Err(format!(
                    "{at}.name: '{}' is also objects[{j}]'s name (names are unique)",
                    obj.name
                ));
            }
            objects.push(obj);
        }
        Ok(EditFile {
            path: path.to_path_buf(),
            metres_per_unit,
            background,
            objects,
        })
    }

    /// The file as JSON (model paths as given).
    pub fn to_json(&self) -> Value {
        let background = match &self.background {
            Background::Model { given, .. } => json!({ "model": given }),
            Background::Color(c) => json!({ "color": hex_colour(*c) }),
        };
        let objects: Vec<Value> = self
            .objects
            .iter()
            .map(|o| {
                let mut m = Map::new();
                m.insert("name".into(), json!(o.name));
                m.insert("model".into(), json!(o.model_given));
                m.insert("visible".into(), json!(o.visible));
                if let Some(k) = o.metres_per_unit {
                    m.insert("metres_per_unit".into(), json!(k));
                }
                if let Some(p) = o.pivot {
                    m.insert("pivot".into(), json!(p.to_array()));
                }
                m.insert("translation".into(), json!(o.translation.to_array()));
                let q = o.rotation;
                m.insert(
                    "rotation".into(),
                    json!({"w": q.w, "x": q.x, "y": q.y, "z": q.z}),
                );
                m.insert("scale".into(), json!(o.scale));
                match o.recolour {
                    Some(Recolour::Target { rgb, strength }) => {
                        m.insert(
                            "recolour".into(),
                            json!({"target": hex_colour(rgb), "strength": strength}),
                        );
                    }
                    Some(Recolour::Hue { degrees, strength }) => {
                        m.insert(
                            "recolour".into(),
                            json!({"hue_degrees": degrees, "strength": strength}),
                        );
                    }
                    None => {}
                }
                Value::Object(m)
            })
            .collect();
        json!({
            "version": EDIT_VERSION,
            "metres_per_unit": self.metres_per_unit,
            "background": background,
            "objects": objects,
        })
    }

    /// Write the file to `self.path`, atomically.
    pub fn write(&self) -> Result<()> {
        let text = serde_json::to_string_pretty(&self.to_json())
            .map_err(|e| Error::json(&self.path, e))?;
        write_atomic(&self.path, |w| {
            w.write_all(text.as_bytes())?;
            w.write_all(b"\n")
        })
    }
}

impl EditObject {
    /// An object of `model` left where it was captured.
    pub fn in_place(name: &str, model_given: &str, model: PathBuf) -> EditObject {
        EditObject {
            name: name.to_string(),
            model_given: model_given.to_string(),
            model,
            visible: true,
            metres_per_unit: None,
            pivot: None,
            translation: DVec3::ZERO,
            rotation: DQuat::IDENTITY,
            scale: 1.0,
            recolour: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> std::result::Result<EditFile, String> {
        EditFile::parse(Path::new("/runs/edit.json"), text.as_bytes()).map_err(|e| e.to_string())
    }

    #[test]
    fn the_documented_example_reads() {
        let e = parse(
            r##"{"version": 1, "metres_per_unit": 1.0,
              "background": {"model": "removed/background.objf"},
              "objects": [
                {"name": "mug", "model": "mug/model.objf", "visible": true,
                 "pivot": [0.42, -0.31, 0.09], "translation": [0.15, 0.0, 0.0],
                 "rotation": {"w": 0.7071068, "x": 0.0, "y": 0.0, "z": 0.7071068},
                 "scale": 1.0, "recolour": {"target": "#2050ff", "strength": 1.0}},
                {"name": "lego", "model": "../lego_run/lego/model.objf",
                 "metres_per_unit": 0.25, "pivot": [0.0, 0.0, 0.3],
                 "translation": [0.1, 0.2, 0.05]}]}"##,
        )
        .unwrap();
        assert_eq!(
            e.background,
            Background::Model {
                given: "removed/background.objf".into(),
                path: "/runs/removed/background.objf".into()
            }
        );
        assert_eq!(
            e.objects[1].model,
            Path::new("/runs/../lego_run/lego/model.objf")
        );
        assert!((e.objects[0].rotation.length() - 1.0).abs() < 1e-12);
        assert_eq!(e.objects[1].scale, 1.0);
        assert_eq!(e.objects[1].metres_per_unit, Some(0.25));
        // Written and read back: the same edit.
        let text = serde_json::to_string(&e.to_json()).unwrap();
        assert_eq!(parse(&text).unwrap(), e);
    }

    #[test]
    fn errors_name_the_field() {
        let base = |obj: &str| {
            format!(
                r##"{{"version": 1, "background": {{"color": "#ffffff"}}, "objects": [{obj}]}}"##
            )
        };
        let cases = [
            (
                r#"{"name": "a", "model": "m.objf", "scale": 0}"#,
                "objects[0].scale: 0 is not a positive number",
            ),
            (
                r#"{"name": "a", "model": "m.objf", "colour": 1}"#,
                "objects[0].colour: unknown key",
            ),
            (r#"{"name": "a"}"#, "objects[0].model: missing"),
            (
                r#"{"name": "a", "model": "m.objf", "rotation": {"w": 0, "x": 0, "y": 0, "z": 0}}"#,
                "objects[0].rotation: a zero quaternion",
            ),
            (
                r#"{"name": "a", "model": "m.objf", "pivot": [1, 2]}"#,
                "objects[0].pivot",
            ),
            (
                r#"{"name": "a", "model": "m.objf", "recolour": {"target": "blue"}}"#,
                "objects[0].recolour.target: 'blue' is not a colour",
            ),
            (
                r#"{"name": "a", "model": "m.objf", "recolour": {"hue_degrees": 30, "strength": 2}}"#,
                "objects[0].recolour.strength",
            ),
            (
                r#"{"name": "a", "model": "m.objf"}, {"name": "a", "model": "n.objf"}"#,
                "objects[1].name: 'a' is also objects[0]'s name",
            ),
        ];
        for (obj, want) in cases {
            let err = parse(&base(obj)).unwrap_err();
            assert!(
                err.contains("/runs/edit.json") && err.contains(want),
                "{err}"
            );
        }
        for (text, want) in [
            (
                r##"{"version": 2, "background": {"color": "#000000"}, "objects": []}"##,
                "version: 2",
            ),
            (r##"{"version": 1, "objects": []}"##, "background: missing"),
            (
                r##"{"version": 1, "background": {"color": "#000000"}, "objects": [], "extra": 1}"##,
                "unknown key 'extra'",
            ),
            (
                r##"{"version": 1, "background": {"color": "#000000", "model": "a"}, "objects": []}"##,
                "exactly one",
            ),
        ] {
            let err = parse(text).unwrap_err();
            assert!(err.contains(want), "{err}");
        }
    }
}
