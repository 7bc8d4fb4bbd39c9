//! `objnerf train`: one field from a capture, saved as a model file: an object's field from its
//! masks ([`fit_object`]), or a field of the whole scene in the space its layout calls for
//! ([`SceneFit`]). The options are built once by the caller and read here by reference.

use crate::error::Result;
use crate::field::io::{self, IDENTITY};
use crate::field::train::StepStats;
use crate::field::MaskSource;
use crate::fit::{
    fit_object, model_notes, FieldKind, FitOptions, Fitted, SceneFit, SceneFitOptions, TrainReport,
    SCENE_FIT_VIEWS,
};
use crate::scene::Scene;
use crate::space::SpaceChoice;
use crate::util::Progress;
use std::path::{Path, PathBuf};

/// Which field to train.
#[derive(Clone, Debug)]
pub enum FieldTarget {
    /// One object, from its masks; or continue the model at `resume`.
    Object {
        masks: MaskSource,
        resume: Option<PathBuf>,
    },
    /// The whole scene, in this space.
    Scene { space: SpaceChoice },
}

impl FieldTarget {
    pub fn kind(&self) -> FieldKind {
        match self {
            FieldTarget::Object { .. } => FieldKind::Object,
            FieldTarget::Scene { .. } => FieldKind::Scene,
        }
    }
}

/// Train the field `target` names on `scene` with `fit` (its `exclude_views` left out);
/// `progress` sees the training (counted in seconds when it trains for a whole budget, else
/// in steps) and a note of the space a scene field chose, before it trains.
pub fn train_field(
    scene: &Scene,
    target: &FieldTarget,
    fit: &FitOptions,
    progress: &dyn Progress,
) -> Result<Fitted> {
    let seconds = fit.time_budget.filter(|_| fit.whole_budget);
    let on_step = |s: &StepStats| {
        let done = if seconds.is_some() {
            s.seconds
        } else {
            s.step as f64
        };
        progress.advance(done as u64, s.detail())
    };
    let begin = || match seconds {
        Some(s) => progress.begin("train (s)", s.ceil() as u64),
        None => progress.begin("train", fit.schedule_steps() as u64),
    };
    let fitted = match target {
        FieldTarget::Object { masks, resume } => {
            let resume = resume.as_deref().map(io::load).transpose()?;
            begin();
            fit_object(scene, masks, fit, resume, &mut { on_step })?
        }
        FieldTarget::Scene { space } => {
            let opts = SceneFitOptions {
                space: *space,
                fit: fit.clone(),
                ..Default::default()
            };
            let mut field = SceneFit::new(scene, &opts)?;
            progress.note(&format!("space: {}", field.space_choice()));
            begin();
            field.train(&fit.stop_rule(), &mut { on_step });
            field.check_fit(SCENE_FIT_VIEWS);
            field.finish()
        }
    };
    progress.end();
    Ok(fitted)
}

/// Train the field `target` names on `scene` and save it at `out`; returns the training report.
pub fn train(
    scene: &Scene,
    target: &FieldTarget,
    fit: &FitOptions,
    out: &Path,
    progress: &dyn Progress,
) -> Result<TrainReport> {
    let fitted = train_field(scene, target, fit, progress)?;
    let notes = model_notes(target.kind(), scene, fit, &fitted.report);
    io::save(out, &fitted.trainer.parts(IDENTITY, notes))?;
    Ok(fitted.report)
}
