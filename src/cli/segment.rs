//! `objnerf segment`, and the clicks it shares with `extract`.

use super::{print_json, print_warnings};
use crate::cli::progress_bars::Bars;
use clap::{ArgMatches, Args};
use objnerf::sam::prompt::{parse_box, parse_point};
use objnerf::segment::PropagationOptions;
use objnerf::segment::{check_request, segment_scene, ObjectPrompt, PointPrompt};
use objnerf::{Error, Result, Scene};
use std::path::PathBuf;

/// The scene and the clicks, shared by `segment` and `extract`. The options' order on the
/// command line matters (see [`prompts_in_order`]); clap only declares them.
#[derive(Args, Debug)]
pub struct ClickArgs {
    /// A scene with 2D-3D tracks (a COLMAP model, or any scene after `objnerf sfm`).
    pub scene: PathBuf,
    /// The view the clicks are in (name, file name, stem or index); applies to the objects after it.
    #[arg(long)]
    pub view: Vec<String>,
    /// Start a new object with this name; the --point options after it belong to it.
    #[arg(long)]
    pub object: Vec<String>,
    /// A click x,y[,fg|bg] in pixels (corner origin) on the current object.
    #[arg(long, allow_hyphen_values = true)]
    pub point: Vec<String>,
    /// A box X0,Y0,X1,Y1 around the current object in its view, with its clicks (SAM's box
    /// prompt for the first mask).
    #[arg(long = "box", value_name = "X0,Y0,X1,Y1")]
    pub bbox: Vec<String>,
}

/// Which of the click options a value came from.
#[derive(Clone, Copy)]
enum Click {
    View,
    Object,
    Point,
    Box,
}

/// Group `--view/--object/--point` by their order on the command line (clap's value indices):
/// points belong to the object named before them, an object to the view named before it (or the
/// first view given). The library checks the result ([`check_request`]).
pub fn prompts_in_order(m: &ArgMatches, scene: &Scene) -> Result<Vec<ObjectPrompt>> {
    let mut clicks: Vec<(usize, Click, &str)> = Vec::new();
    for (id, kind) in [
        ("view", Click::View),
        ("object", Click::Object),
        ("point", Click::Point),
        ("bbox", Click::Box),
    ] {
        if let (Some(idx), Some(vals)) = (m.indices_of(id), m.get_many::<String>(id)) {
            clicks.extend(idx.zip(vals).map(|(i, v)| (i, kind, v.as_str())));
        }
    }
    clicks.sort_by_key(|c| c.0);
    let mut objects: Vec<ObjectPrompt> = Vec::new();
    let mut view: Option<usize> = None;
    for (_, kind, value) in clicks {
        match kind {
            Click::View => {
                let v = value;
                let v = scene.find_image(v)?;
                view = Some(v);
                // A view given right after an object (before its points) is that object's view.
                if let Some(o) = objects.last_mut().filter(|o| o.points.is_empty()) {
                    o.view = v;
                }
            }
            Click::Object => objects.push(new_object(value, view)),
            Click::Point => {
                if objects.is_empty() {
                    objects.push(new_object("object", view));
                }
                let p = parse_point(value)?;
                let o = objects.last_mut().expect("an object was just made");
                o.points.push(PointPrompt {
                    xy: [p.x as f64, p.y as f64],
                    positive: p.positive,
                });
            }
            Click::Box => {
                let b = parse_box(value)?;
                if objects.is_empty() {
                    objects.push(new_object("object", view));
                }
                let o = objects.last_mut().expect("an object was just made");
                if o.bbox.is_some() {
                    return Err(Error::invalid(format!(
                        "object '{}' has two --box options: give one",
                        o.name
                    )));
                }
                o.bbox = Some(b.map(f64::from));
            }
        }
    }
    for o in &mut objects {
        if o.view == usize::MAX {
            o.view =
                view.ok_or_else(|| Error::invalid("give the clicked view with --view NAME"))?;
        }
    }
    Ok(objects)
}

/// An object whose view is not known yet is marked `usize::MAX` until the first --view.
fn new_object(name: &str, view: Option<usize>) -> ObjectPrompt {
    ObjectPrompt {
        name: name.to_string(),
        view: view.unwrap_or(usize::MAX),
        points: vec![],
        bbox: None,
    }
}

#[derive(Args, Debug)]
pub struct SegmentCmd {
    #[command(flatten)]
    pub clicks: ClickArgs,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
    /// Positive prompts per view.
    #[arg(long, default_value_t = PropagationOptions::default().max_prompts)]
    pub prompts: usize,
    /// Coverage of the expected (alpha-shape) mask below which a view is obstructed.
    #[arg(long, default_value_t = PropagationOptions::default().obstruction_coverage)]
    pub obstruction_coverage: f64,
    /// Replace the output folder if it exists.
    #[arg(long)]
    pub overwrite: bool,
    /// Print report.json to stdout too.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub sam: super::models::SamPrecisionArg,
}

impl SegmentCmd {
    pub fn run(self, m: &ArgMatches) -> Result<()> {
        let scene = Scene::load(&self.clicks.scene)?;
        let prompts = prompts_in_order(m, &scene)?;
        check_request(&scene, &prompts)?;
        let opts = PropagationOptions {
            max_prompts: self.prompts,
            obstruction_coverage: self.obstruction_coverage,
            ..Default::default()
        };
        let seg = self.sam.segmenter()?;
        let (report, _) = segment_scene(
            &scene,
            &prompts,
            &opts,
            &seg,
            &self.out,
            self.overwrite,
            &Bars::default(),
        )?;
        if self.json {
            print_json(&report);
        }
        for o in &report.objects {
            println!(
                "{}: {} ok, {} obstructed, {} absent of {} views; {} points -> {}",
                o.name,
                o.num_ok,
                o.num_obstructed,
                o.num_absent,
                o.views.len(),
                o.num_points,
                self.out.join("masks").join(&o.name).display()
            );
        }
        println!(
            "{:.1} s (encoder {:.1} s over {} runs, decoder {:.1} s)",
            report.timings.total,
            report.timings.encoder,
            report.encoder_runs,
            report.timings.decoder
        );
        print_warnings(&report.warnings);
        Ok(())
    }
}
