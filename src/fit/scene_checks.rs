//! Self-checks of a trained scene field, on its own training views: whether it reproduces them
//! (a field that does not is blurred, or full of floaters, in every render made from it), and
//! whether it renders them see-through where they saw a surface.

use crate::field::eval::{truth_on, Rendered};
use crate::field::view::View;
use crate::util::warnings::{Stage, Warning};
use serde::Serialize;

/// A scene field reproducing its own training views (where they carry a loss) under this PSNR
/// (dB, full frame) is blurred or full of floaters where a person looks: the demo scene's
/// whole-ring field at 20-21 dB shows smeared backdrop and speckled far floor; its edit
/// background at 25.8 dB renders the edits above 26 dB against their truth.
pub const MIN_SCENE_FIT_PSNR: f64 = 24.0;
/// A scene field is opaque wherever a training view saw something; the worst view's share of
/// such pixels rendered with opacity below [`SEE_THROUGH_ALPHA`] above this shows as specks of
/// the background colour (white) in renders: the demo's mug-and-torus removal had 0.1-0.6%.
pub const MAX_SCENE_SEE_THROUGH: f64 = 0.001;
/// Opacity under which a rendered pixel counts as see-through.
pub const SEE_THROUGH_ALPHA: f32 = 0.5;

/// How well a scene field reproduces its training views (renders on white, alpha included).
#[derive(Clone, Debug, Default, Serialize)]
pub struct SceneFitCheck {
    pub views: usize,
    /// PSNR over every loss-carrying pixel of the views, on white.
    pub psnr: f64,
    /// The worst view's share of loss-carrying pixels rendered see-through, and its name.
    pub see_through: f64,
    pub see_through_view: String,
}

/// Measure a scene field's `renders` (on white) of its training `views` where they carry a loss.
pub fn measure_scene_fit(views: &[View], renders: &[Rendered]) -> SceneFitCheck {
    let mut out = SceneFitCheck {
        views: views.len(),
        ..Default::default()
    };
    let (mut se, mut n) = (0.0f64, 0usize);
    for (v, r) in views.iter().zip(renders) {
        let truth = truth_on(v, [1.0; 3]);
        let (mut clear, mut count) = (0usize, 0usize);
        for i in 0..truth.len() {
            if v.loss_mask.as_ref().is_some_and(|m| !m[i]) {
                continue;
            }
            count += 1;
            clear += (r.alpha[i] < SEE_THROUGH_ALPHA) as usize;
            se += (0..3)
                .map(|c| ((r.rgb[i][c] - truth[i][c]) as f64).powi(2))
                .sum::<f64>();
        }
        n += 3 * count;
        let frac = clear as f64 / count.max(1) as f64;
        if frac >= out.see_through {
            out.see_through = frac;
            out.see_through_view = v.name.clone();
        }
    }
    out.psnr = -10.0 * (se / n.max(1) as f64).max(1e-20).log10();
    out
}

/// The warnings a scene field's fit raises: blurred (under [`MIN_SCENE_FIT_PSNR`]) and
/// see-through (over [`MAX_SCENE_SEE_THROUGH`]).
pub fn check_scene_fit(c: &SceneFitCheck) -> Vec<Warning> {
    let mut out = Vec::new();
    if c.views > 0 && c.psnr < MIN_SCENE_FIT_PSNR {
        out.push(Warning::new(
            Stage::Field,
            "scene_field_blurred",
            c.psnr,
            MIN_SCENE_FIT_PSNR,
            format!(
                "the scene field reproduces its own {} training views at {:.1} dB: renders will be blurred, with floaters where the views see surfaces far away or at grazing angles; train longer (--steps), at a lower resolution (--downscale 2) or with more memory (--memory-mb)",
                c.views, c.psnr
            ),
        ));
    }
    if c.see_through > MAX_SCENE_SEE_THROUGH {
        out.push(Warning::new(
            Stage::Field,
            "scene_field_see_through",
            c.see_through,
            MAX_SCENE_SEE_THROUGH,
            format!(
                "{:.2}% of {}'s pixels render see-through (opacity below {SEE_THROUGH_ALPHA}) although the view saw a surface there: renders show specks of the background colour; train longer",
                100.0 * c.see_through,
                c.see_through_view
            ),
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Camera, Pose};
    use glam::DVec3;

    const N: usize = 400;

    /// A 20 x 20 view of grey, and a render of it: exact but for `clear` pixels rendered white
    /// and see-through, and with `hole` pixels carrying no loss.
    fn case(clear: usize, hole: usize) -> (View, Rendered) {
        let cam = Camera::pinhole(20, 20, 20.0, 20.0, 10.0, 10.0);
        let pose = Pose::look_at(DVec3::new(0.0, 0.0, -3.0), DVec3::ZERO, DVec3::Y);
        let mut v = View::new("v.png".into(), cam, pose, vec![[128, 128, 128, 255]; N]);
        v.loss_mask = Some((0..N).map(|i| i >= hole).collect());
        let grey = 128.0 / 255.0;
        let r = Rendered {
            width: 20,
            height: 20,
            rgb: (0..N)
                .map(|i| if i < clear { [1.0; 3] } else { [grey; 3] })
                .collect(),
            alpha: (0..N).map(|i| if i < clear { 0.0 } else { 1.0 }).collect(),
            depth: vec![1.0; N],
        };
        (v, r)
    }

    #[test]
    fn a_faithful_field_passes_and_a_see_through_one_is_flagged() {
        let (v, r) = case(0, 0);
        let c = measure_scene_fit(std::slice::from_ref(&v), std::slice::from_ref(&r));
        assert!(c.psnr > 60.0 && c.see_through == 0.0, "{c:?}");
        assert!(check_scene_fit(&c).is_empty());

        // 1 of 400 pixels white: squared error 0.25 / 400 -> 32 dB, 0.25% see-through.
        let (v, r) = case(1, 0);
        let c = measure_scene_fit(std::slice::from_ref(&v), std::slice::from_ref(&r));
        assert!(
            (c.see_through - 0.0025).abs() < 1e-9 && c.psnr < 33.0,
            "{c:?}"
        );
        let codes: Vec<_> = check_scene_fit(&c).iter().map(|w| w.code).collect();
        assert_eq!(codes, ["scene_field_see_through"]);
    }

    #[test]
    fn pixels_without_a_loss_are_not_scored() {
        // The same white pixel inside a removed object's hole: nothing to flag.
        let (v, r) = case(1, 1);
        let c = measure_scene_fit(std::slice::from_ref(&v), std::slice::from_ref(&r));
        assert!(c.psnr > 60.0 && c.see_through == 0.0, "{c:?}");

        // A field that misses everything is blurred.
        let (v, r) = case(N, 0);
        let c = measure_scene_fit(std::slice::from_ref(&v), std::slice::from_ref(&r));
        let codes: Vec<_> = check_scene_fit(&c).iter().map(|w| w.code).collect();
        assert_eq!(codes, ["scene_field_blurred", "scene_field_see_through"]);
    }
}
