//! COLMAP's command lines, per program and per COLMAP version, and the feature extraction,
//! matching and mapping runs built from them.

use super::colmap_run::{run_colmap, s, Colmap, ColmapVersion, Steps};
use super::SfmOptions;
use crate::error::{Error, Result};
use std::path::Path;

/// Which image pairs COLMAP matches.
#[derive(Clone, Copy, Debug)]
pub(super) enum Matching<'a> {
    /// Every pair.
    Exhaustive,
    /// Each image with its neighbours in name order (frames of a video).
    Sequential,
    /// These pairs (indices into the staged names), chosen from known poses.
    Pairs(&'a [(usize, usize)]),
}

impl<'a> Matching<'a> {
    /// The matching `--matcher` asks for: "auto" is the pose-chosen pairs for a posed scene,
    /// sequential for a video's frames, else exhaustive.
    pub(super) fn choose(
        matcher: &str,
        pairs: Option<&'a [(usize, usize)]>,
        video: bool,
    ) -> Result<Self> {
        Ok(match (matcher, pairs) {
            ("auto" | "pairs", Some(pairs)) => Matching::Pairs(pairs),
            ("pairs", None) => {
                return Err(Error::invalid(
                    "--matcher pairs needs a posed scene (pairs are chosen from the poses)",
                ))
            }
            ("auto", None) if video => Matching::Sequential,
            ("auto" | "exhaustive", _) => Matching::Exhaustive,
            ("sequential", _) => Matching::Sequential,
            (m, _) => {
                return Err(Error::invalid(format!(
                    "unknown matcher '{m}': use auto, exhaustive, sequential or pairs"
                )))
            }
        })
    }
}

fn path_arg(p: &Path) -> String {
    p.display().to_string()
}

/// `colmap feature_extractor`'s arguments for COLMAP `version`.
pub(super) fn feature_extractor_args(
    version: ColmapVersion,
    db: &Path,
    images: &Path,
    opts: &SfmOptions,
    camera_args: &[String],
) -> Vec<String> {
    let section = version.extraction();
    let mut args = vec![
        s("feature_extractor"),
        s("--database_path"),
        path_arg(db),
        s("--image_path"),
        path_arg(images),
        format!("--{section}.use_gpu"),
        s("0"),
        s("--SiftExtraction.max_num_features"),
        opts.max_features.to_string(),
        format!("--{section}.num_threads"),
        opts.threads.to_string(),
    ];
    args.extend_from_slice(camera_args);
    args
}

/// The matcher's arguments for COLMAP `version`; `pair_list` is the file the pairs of
/// [`Matching::Pairs`] are written to.
pub(super) fn matcher_args(
    version: ColmapVersion,
    db: &Path,
    matching: Matching,
    pair_list: &Path,
    opts: &SfmOptions,
) -> Vec<String> {
    let mut args = match matching {
        Matching::Exhaustive => vec![s("exhaustive_matcher")],
        Matching::Sequential => vec![s("sequential_matcher")],
        Matching::Pairs(_) => vec![
            s("matches_importer"),
            s("--match_list_path"),
            path_arg(pair_list),
            s("--match_type"),
            s("pairs"),
        ],
    };
    let section = version.matching();
    args.extend([
        s("--database_path"),
        path_arg(db),
        format!("--{section}.use_gpu"),
        s("0"),
        format!("--{section}.num_threads"),
        opts.threads.to_string(),
    ]);
    args
}

/// The mapper's arguments (full reconstruction), or the point triangulator's when `input` is
/// the known model to triangulate; the same in every version objnerf runs.
pub(super) fn mapper_args(
    db: &Path,
    images: &Path,
    input: Option<&Path>,
    output: &Path,
    opts: &SfmOptions,
) -> Vec<String> {
    let program = if input.is_some() {
        "point_triangulator"
    } else {
        "mapper"
    };
    let mut args = vec![
        s(program),
        s("--database_path"),
        path_arg(db),
        s("--image_path"),
        path_arg(images),
    ];
    if let Some(input) = input {
        args.extend([s("--input_path"), path_arg(input)]);
    }
    args.extend([
        s("--output_path"),
        path_arg(output),
        s("--Mapper.num_threads"),
        opts.threads.to_string(),
    ]);
    args
}

/// Feature extraction and matching of the staged images (`work/images`) into
/// `work/database.db`.
pub(super) fn extract_and_match(
    colmap: &Colmap,
    work: &Path,
    opts: &SfmOptions,
    camera_args: &[String],
    (matching, staged): (Matching, &[String]),
    steps: &Steps,
) -> Result<()> {
    let db = work.join("database.db");
    let log = work.join("colmap.log");
    let args = feature_extractor_args(colmap.version, &db, &work.join("images"), opts, camera_args);
    run_colmap(colmap, &args, &log, steps)?;
    let list = work.join("pairs.txt");
    if let Matching::Pairs(pairs) = matching {
        let text: String = pairs
            .iter()
            .map(|&(i, j)| format!("{} {}\n", staged[i], staged[j]))
            .collect();
        std::fs::write(&list, text).map_err(|e| Error::io(&list, e))?;
    }
    let args = matcher_args(colmap.version, &db, matching, &list, opts);
    run_colmap(colmap, &args, &log, steps)
}

/// Run the mapper (full reconstruction) or the point triangulator (known poses) on the staged
/// images' database, writing into `output`; `input` is the known model to triangulate.
pub(super) fn map_points(
    colmap: &Colmap,
    work: &Path,
    input: Option<&Path>,
    output: &Path,
    opts: &SfmOptions,
    steps: &Steps,
) -> Result<()> {
    std::fs::create_dir_all(output).map_err(|e| Error::io(output, e))?;
    let args = mapper_args(
        &work.join("database.db"),
        &work.join("images"),
        input,
        output,
        opts,
    );
    run_colmap(colmap, &args, &work.join("colmap.log"), steps)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every `Section.name` option COLMAP registers, from its source at that release
    /// (tests/data/colmap/options-*.txt say which file and commit).
    fn known_options(list: &str) -> std::collections::HashSet<&str> {
        list.lines().filter(|l| !l.starts_with('#')).collect()
    }

    /// All command lines of a full reconstruction and of a triangulation.
    fn command_lines(v: ColmapVersion) -> Vec<Vec<String>> {
        let opts = SfmOptions::default();
        let (db, img, out) = (Path::new("w/db"), Path::new("w/images"), Path::new("o"));
        let cams = [s("--ImageReader.single_camera"), s("1")];
        let pairs = [(0, 1)];
        vec![
            feature_extractor_args(v, db, img, &opts, &cams),
            matcher_args(v, db, Matching::Exhaustive, out, &opts),
            matcher_args(v, db, Matching::Sequential, out, &opts),
            matcher_args(v, db, Matching::Pairs(&pairs), out, &opts),
            mapper_args(db, img, None, out, &opts),
            mapper_args(db, img, Some(out), out, &opts),
        ]
    }

    fn dotted(lines: &[Vec<String>]) -> Vec<String> {
        let mut v: Vec<String> = lines
            .iter()
            .flatten()
            .filter_map(|a| a.strip_prefix("--"))
            .filter(|a| a.contains('.'))
            .map(String::from)
            .collect();
        v.sort();
        v.dedup();
        v
    }

    #[test]
    fn version_from_help_text() {
        let v = |t: &str| ColmapVersion::from_help(t);
        assert_eq!(
            v("COLMAP 3.8 -- Structure-from-Motion and Multi-View Stereo\n  (Commit Unknown)"),
            Some(ColmapVersion::new(3, 8, 0))
        );
        assert_eq!(
            v("COLMAP 3.13.0 -- Structure-from-Motion and Multi-View Stereo\n(Commit 1234)"),
            Some(ColmapVersion::new(3, 13, 0))
        );
        assert_eq!(
            v("COLMAP 4.1.1 (Commit abc on 2025-01-01 with CUDA)"),
            Some(ColmapVersion::new(4, 1, 1))
        );
        assert_eq!(
            v("COLMAP 3.14.0.dev0 -- x"),
            Some(ColmapVersion::new(3, 14, 0))
        );
        assert_eq!(v("colmap: command not found"), None);
        assert_eq!(v("COLMAP -- no number"), None);
    }

    #[test]
    fn option_names_follow_the_version() {
        let old = command_lines(ColmapVersion::new(3, 8, 0));
        let new = command_lines(ColmapVersion::new(3, 13, 0));
        assert_eq!(
            dotted(&old),
            [
                "ImageReader.single_camera",
                "Mapper.num_threads",
                "SiftExtraction.max_num_features",
                "SiftExtraction.num_threads",
                "SiftExtraction.use_gpu",
                "SiftMatching.num_threads",
                "SiftMatching.use_gpu",
            ]
        );
        assert_eq!(
            dotted(&new),
            [
                "FeatureExtraction.num_threads",
                "FeatureExtraction.use_gpu",
                "FeatureMatching.num_threads",
                "FeatureMatching.use_gpu",
                "ImageReader.single_camera",
                "Mapper.num_threads",
                "SiftExtraction.max_num_features",
            ]
        );
        // The renaming starts at 3.13.0: 3.12 keeps the old names, 4.x the new ones.
        assert_eq!(
            dotted(&command_lines(ColmapVersion::new(3, 12, 6))),
            dotted(&old)
        );
        assert_eq!(
            dotted(&command_lines(ColmapVersion::new(4, 1, 1))),
            dotted(&new)
        );
        // Every other argument is the same in both.
        let strip = |lines: Vec<Vec<String>>| -> Vec<Vec<String>> {
            lines
                .into_iter()
                .map(|l| l.into_iter().filter(|a| !a.contains('.')).collect())
                .collect()
        };
        assert_eq!(strip(old), strip(new));
    }

    #[test]
    fn every_option_exists_in_that_release() {
        for (v, list) in [
            (
                ColmapVersion::new(3, 8, 0),
                include_str!("../../../tests/data/colmap/options-3.8.txt"),
            ),
            (
                ColmapVersion::new(3, 13, 0),
                include_str!("../../../tests/data/colmap/options-3.13.0.txt"),
            ),
        ] {
            let known = known_options(list);
            assert!(known.len() > 150, "{v}: {} options", known.len());
            let mut lines = command_lines(v);
            // The camera arguments triangulation passes.
            lines.push(vec![
                s("--ImageReader.single_camera_per_image"),
                s("--ImageReader.camera_model"),
                s("--ImageReader.camera_params"),
            ]);
            for opt in dotted(&lines) {
                assert!(known.contains(opt.as_str()), "COLMAP {v} has no --{opt}");
            }
        }
    }

    #[test]
    fn auto_matching_by_input() {
        let pairs = [(0, 1)];
        assert!(matches!(
            Matching::choose("auto", Some(&pairs), false).unwrap(),
            Matching::Pairs(_)
        ));
        assert!(matches!(
            Matching::choose("auto", None, true).unwrap(),
            Matching::Sequential
        ));
        assert!(matches!(
            Matching::choose("auto", None, false).unwrap(),
            Matching::Exhaustive
        ));
        assert!(Matching::choose("pairs", None, false).is_err());
        assert!(Matching::choose("vocab", None, false).is_err());
    }
}
