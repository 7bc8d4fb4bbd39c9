//! Self-checks: what a stage noticed about its own result that the user should act on. Every
//! stage checks its output against named thresholds and returns [`Warning`]s; commands write
//! them into report.json as `warnings` and print them at the end. The aim is that no bad result
//! is handed over silently: a result is good, or it carries a warning that says why it may not
//! be. `docs/self-checks.md` lists every check with its floor and the reason for it
//! (`tests/self_checks.rs` holds the list to the code).

use serde::Serialize;

/// The stage a check belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Stage {
    Scene,
    Segment,
    Field,
    Mesh,
}

impl Stage {
    pub fn name(self) -> &'static str {
        match self {
            Stage::Scene => "scene",
            Stage::Segment => "segment",
            Stage::Field => "field",
            Stage::Mesh => "mesh",
        }
    }
}

/// One tripped check: which (`code`, stable for scripts), where (`stage`, and the object when
/// the check is about one), what it means and what to do (`message`), and the figure that
/// tripped it against its threshold.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Warning {
    pub code: &'static str,
    pub stage: Stage,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub object: Option<String>,
    pub message: String,
    pub figure: f64,
    pub threshold: f64,
}

impl Warning {
    pub fn new(
        stage: Stage,
        code: &'static str,
        figure: f64,
        threshold: f64,
        message: impl Into<String>,
    ) -> Self {
        Warning {
            code,
            stage,
            object: None,
            message: message.into(),
            figure,
            threshold,
        }
    }

    /// The same warning, about `object`.
    pub fn about(mut self, object: &str) -> Self {
        self.object = Some(object.to_string());
        self
    }

    /// One line for a person: `[stage] object: message (code: figure vs threshold)`.
    pub fn line(&self) -> String {
        let who = self
            .object
            .as_deref()
            .map(|o| format!("{o}: "))
            .unwrap_or_default();
        format!(
            "[{}] {who}{} ({}: {} against {})",
            self.stage.name(),
            self.message,
            self.code,
            short(self.figure),
            short(self.threshold)
        )
    }
}

/// The first few of `names` joined, and how many more there are: warnings name the views they
/// are about without growing past a line.
pub fn name_list(names: &[&str]) -> String {
    const SHOWN: usize = 5;
    let mut s = names
        .iter()
        .take(SHOWN)
        .copied()
        .collect::<Vec<_>>()
        .join(", ");
    if names.len() > SHOWN {
        s += &format!(" and {} more", names.len() - SHOWN);
    }
    s
}

/// A figure in few digits (counts as integers).
fn short(v: f64) -> String {
    if v.fract() == 0.0 && v.abs() < 1e9 {
        format!("{v:.0}")
    } else if v.abs() >= 100.0 {
        format!("{v:.1}")
    } else {
        format!("{v:.3}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_warning_reads_as_one_line() {
        let w = Warning::new(
            Stage::Field,
            "heldout_psnr_low",
            17.25,
            20.0,
            "held-out views",
        )
        .about("mug");
        assert_eq!(
            w.line(),
            "[field] mug: held-out views (heldout_psnr_low: 17.250 against 20)"
        );
        let j = serde_json::to_value(&w).unwrap();
        assert_eq!(j["stage"], "field");
        assert_eq!(j["figure"], 17.25);
    }
}
