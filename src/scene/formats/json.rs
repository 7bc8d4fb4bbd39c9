//! JSON as objnerf reads it: bytes checked as UTF-8, and a syntax error that a bare `NaN` or
//! `Infinity` explains (Python's json module writes them) says so and where.

use crate::error::{Error, Result};
use std::path::Path;

/// Parse a JSON file written by nerfstudio (or for it) into `T`.
pub(crate) fn read_json_file<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    parse_json(path, &bytes)
}

/// Where the first bare `NaN` / `Infinity` (outside strings) of a JSON text sits, as a path of
/// keys and indices (`camera_path[0].camera_to_world[3]`).
fn nonfinite_path(text: &str) -> Option<String> {
    // The containers open at the current position: an object's last key, or an array's index.
    enum Open {
        Object(Option<String>),
        Array(usize),
    }
    let b = text.as_bytes();
    let mut stack: Vec<Open> = Vec::new();
    let mut i = 0;
    let mut expect_key = false;
    while i < b.len() {
        match b[i] {
            b'"' => {
                let start = i + 1;
                i += 1;
                while i < b.len() && b[i] != b'"' {
                    i += if b[i] == b'\\' { 2 } else { 1 };
                }
                if expect_key {
                    if let Some(Open::Object(k)) = stack.last_mut() {
                        *k = Some(text.get(start..i.min(b.len()))?.to_string());
                    }
                    expect_key = false;
                }
            }
            b'{' => {
                stack.push(Open::Object(None));
                expect_key = true;
            }
            b'[' => stack.push(Open::Array(0)),
            b'}' | b']' => {
                stack.pop();
            }
            b',' => match stack.last_mut() {
                Some(Open::Array(n)) => *n += 1,
                Some(Open::Object(_)) => expect_key = true,
                None => {}
            },
            b'N' | b'I' | b'-'
                if text[i..].starts_with("NaN")
                    || text[i..].starts_with("Infinity")
                    || text[i..].starts_with("-Infinity") =>
            {
                let mut p = String::new();
                for o in &stack {
                    match o {
                        Open::Object(Some(k)) => {
                            if !p.is_empty() {
                                p.push('.');
                            }
                            p.push_str(k);
                        }
                        Open::Object(None) => {}
                        Open::Array(n) => p.push_str(&format!("[{n}]")),
                    }
                }
                return Some(if p.is_empty() { "the value".into() } else { p });
            }
            _ => {}
        }
        i += 1;
    }
    None
}

/// JSON from a file's bytes (`path` names it in errors): UTF-8 checked, and a syntax error
/// that NaN or Infinity explains says so.
pub(crate) fn parse_json<T: serde::de::DeserializeOwned>(path: &Path, bytes: &[u8]) -> Result<T> {
    let text = super::text(path, bytes)?;
    serde_json::from_str(text).map_err(|e| {
        // Python's json module writes non-finite floats as bare NaN/Infinity: say so, and where.
        if e.is_syntax() && (text.contains("NaN") || text.contains("Infinity")) {
            let at = nonfinite_path(text)
                .map(|p| format!("{p} is NaN or Infinity"))
                .unwrap_or_else(|| "the file holds NaN or Infinity".into());
            Error::format(
                path,
                format!("invalid JSON: {e} ({at}, which JSON does not allow: a non-finite pose or number?)"),
            )
        } else {
            Error::json(path, e)
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nan_is_found_by_its_path() {
        let t = r#"{"a": 1, "camera_path": [{"fov": 1}, {"camera_to_world": [1, 2, NaN], "x": "NaN"}]}"#;
        assert_eq!(
            nonfinite_path(t).as_deref(),
            Some("camera_path[1].camera_to_world[2]")
        );
        let e = parse_json::<serde_json::Value>(Path::new("p.json"), t.as_bytes()).unwrap_err();
        assert!(
            e.to_string()
                .contains("camera_path[1].camera_to_world[2] is NaN"),
            "{e}"
        );
        assert_eq!(
            nonfinite_path(r#"{"s": "NaN \" x", "v": -Infinity}"#).as_deref(),
            Some("v")
        );
    }
}
