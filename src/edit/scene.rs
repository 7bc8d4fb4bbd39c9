//! An edit file with its fields loaded: each object placed in the edit's frame by a
//! [`Similarity`], duplicates sharing one loaded field. Every error names the edit file and the
//! field that led to it (`edit.json: objects[0].model: ...`).

use super::file::{Background, EditFile};
use super::recolour::Recolour;
use super::similarity::Similarity;
use crate::error::{Error, Result};
use crate::field::io::{load_field, Model};
use crate::field::{Field, RenderOptions};
use crate::space::Space;
use glam::DVec3;
use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::Arc;

/// The background, loaded.
#[derive(Clone, Debug)]
pub enum LoadedBackground {
    Field(Arc<Model>),
    Color([f32; 3]),
}

/// One object of the edit, placed.
#[derive(Clone, Debug)]
pub struct Placed {
    pub name: String,
    /// Its position in the edit file's `objects` (its object-index pass value is this + 1).
    pub index: usize,
    pub model: Arc<Model>,
    /// Model frame -> the edit's frame.
    pub to_world: Similarity,
    /// The pivot used, in the model's frame.
    pub pivot: DVec3,
    pub recolour: Option<Recolour>,
    pub visible: bool,
}

impl Placed {
    pub fn field(&self) -> &Field {
        &self.model.field
    }

    /// The object's box in the edit's frame (for a box-space field; None for a field of
    /// unbounded or NDC space, which has no box in the world).
    pub fn world_box(&self) -> Option<(DVec3, DVec3)> {
        let f = self.field();
        (f.space == Space::Box).then(|| {
            self.to_world
                .apply_box(f.box_min.as_dvec3(), f.box_max.as_dvec3())
        })
    }
}

/// An edit ready to render.
#[derive(Clone, Debug)]
pub struct LoadedEdit {
    pub file: EditFile,
    pub background: LoadedBackground,
    /// Every object of the file, in its order (the invisible ones too, marked).
    pub objects: Vec<Placed>,
}

impl LoadedEdit {
    pub fn visible(&self) -> impl Iterator<Item = &Placed> {
        self.objects.iter().filter(|o| o.visible)
    }
}

/// The default pivot of a model: the centre of its box (object fields live in world boxes).
pub fn default_pivot(field: &Field) -> Option<DVec3> {
    (field.space == Space::Box).then(|| 0.5 * (field.box_min + field.box_max).as_dvec3())
}

/// Load every model an edit names (each file once) and place its objects. With `render`, each
/// field's occupancy is pruned for those render options: cells whose densest corner stays below
/// the alpha threshold at that step are skipped without being evaluated (exact: such samples
/// are dropped anyway), so empty bricks are jumped over.
pub fn load_edit(file: EditFile, render: Option<&RenderOptions>) -> Result<LoadedEdit> {
    let at = |field: String, e: Error| Error::format(&file.path, format!("{field}: {e}"));
    let mut cache: HashMap<PathBuf, Arc<Model>> = HashMap::new();
    let mut load = |p: &PathBuf| -> Result<Arc<Model>> {
        if let Some(m) = cache.get(p) {
            return Ok(m.clone());
        }
        let mut m = load_field(p)?;
        if let Some(r) = render {
            let f = &mut m.field;
            f.prune_occupancy(r.step * f.voxel / f.config.base_voxel, r.alpha_thresh);
        }
        let m = Arc::new(m);
        cache.insert(p.clone(), m.clone());
        Ok(m)
    };
    let background = match &file.background {
        Background::Color(c) => LoadedBackground::Color(*c),
        Background::Model { path, .. } => {
            LoadedBackground::Field(load(path).map_err(|e| at("background.model".into(), e))?)
        }
    };
    let mut objects = Vec::with_capacity(file.objects.len());
    for (i, o) in file.objects.iter().enumerate() {
        let model = load(&o.model).map_err(|e| at(format!("objects[{i}].model"), e))?;
        let pivot = match o.pivot.or_else(|| default_pivot(&model.field)) {
            Some(p) => p,
            None => {
                return Err(Error::format(
                    &file.path,
                    format!(
                        "objects[{i}].pivot: missing, and {} is a field of {} space, whose box is not a place in the world: give the pivot",
                        o.model.display(),
                        model.field.space.name()
                    ),
                ))
            }
        };
        let k = o.metres_per_unit.unwrap_or(file.metres_per_unit) / file.metres_per_unit;
        objects.push(Placed {
            name: o.name.clone(),
            index: i,
            to_world: Similarity::from_edit(pivot, o.translation, o.rotation, o.scale, k),
            pivot,
            recolour: o.recolour,
            visible: o.visible,
            model,
        });
    }
    Ok(LoadedEdit {
        file,
        background,
        objects,
    })
}
