//! Video in (`objnerf sfm VIDEO`): ffmpeg decodes the video twice, once small and grey to score
//! every frame's sharpness (the variance of its Laplacian: motion blur and defocus lower it),
//! once to write the chosen frames, the sharpest of each of N equal windows of the video
//! (nerfstudio's `ns-process-data video` keeps 300 frames by default; it picks ffmpeg's
//! `thumbnail` of each window, the frame nearest the window's mean histogram, not the sharpest).
//! COLMAP then reconstructs from the frames, matching each with its neighbours in time.

use super::reconstruct::reconstruct_images;
use super::{ImagesOut, Run, SfmOptions, SfmReport, StageTime};
use crate::error::{Error, Result};
use crate::util::{Detail, Progress};
use image::GrayImage;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

/// Frames are scored at most this wide: enough to see blur, small enough to score a long video
/// in seconds.
const SCORE_WIDTH: u32 = 480;

/// What was taken from the video.
#[derive(Clone, Debug, serde::Serialize)]
pub struct VideoReport {
    pub video: PathBuf,
    pub frames_in_video: usize,
    pub frames_chosen: usize,
    /// Mean sharpness (variance of the Laplacian of the grey frame, at most 480 pixels wide) of
    /// the chosen frames and of all frames.
    pub mean_sharpness_chosen: f64,
    pub mean_sharpness_all: f64,
}

/// One chosen frame, as `frames.json` lists it.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ChosenFrame {
    /// The image file's name.
    pub file: String,
    /// The frame's index in the video (0 = first decoded frame).
    pub frame: usize,
    pub sharpness: f64,
}

/// The frames taken from a video by [`take_frames`].
pub struct VideoFrames {
    pub summary: VideoReport,
    pub frames: Vec<ChosenFrame>,
    pub paths: Vec<PathBuf>,
    /// The time spent choosing (decoding every frame small and scoring it) and writing.
    pub stages: Vec<StageTime>,
}

/// Reconstruct from a video: keep the sharpest frame of each of `opts.video_frames` windows in
/// `out/images/frame_NNNNN.jpg` (listed with their video frame and sharpness in
/// `out/frames.json`), then COLMAP as for a folder of images with sequential matching.
pub fn reconstruct_video(
    video: &Path,
    out: &Path,
    opts: &SfmOptions,
    progress: &dyn Progress,
) -> Result<SfmReport> {
    // A file ffmpeg cannot read is refused before COLMAP is looked for and `out` claimed.
    check_video(video, opts.video_frames)?;
    let mut run = Run::begin(out, opts)?;
    let taken = take_frames(
        video,
        opts.video_frames,
        &run.dest.path().join("images"),
        progress,
    )?;
    let list = run.dest.path().join("frames.json");
    let text = serde_json::to_string_pretty(&taken.frames).expect("frames serialise");
    std::fs::write(&list, text).map_err(|e| Error::io(&list, e))?;
    run.stages.extend(taken.stages);
    let mut report =
        reconstruct_images(run, taken.paths, ImagesOut::InPlace, true, opts, progress)?;
    report.video = Some(taken.summary);
    Ok(report)
}

/// The frame count the video's container states (None when it states none), or an error
/// naming the video when ffmpeg cannot read it or `target` is below 2.
fn check_video(video: &Path, target: usize) -> Result<Option<u64>> {
    if target < 2 {
        return Err(Error::invalid(format!(
            "--frames {target}: structure from motion needs at least 2"
        )));
    }
    count_frames(video)
}

/// Choose the sharpest frame of each of `target` equal windows of `video` and write them at
/// full size to `dir/frame_NNNNN.jpg`, numbered from 1 in time order.
pub fn take_frames(
    video: &Path,
    target: usize,
    dir: &Path,
    progress: &dyn Progress,
) -> Result<VideoFrames> {
    let start = Instant::now();
    let expected = check_video(video, target)?;
    let log = tempfile::NamedTempFile::new().map_err(|e| Error::io(std::env::temp_dir(), e))?;
    let scores = score_frames(video, expected, log.path(), progress)?;
    match scores.len() {
        0 => return Err(Error::format(video, "the video has no frames")),
        1 => {
            return Err(Error::format(
                video,
                "the video has one frame; structure from motion needs at least 2",
            ))
        }
        _ => {}
    }
    let chosen = sharpest_per_window(&scores, target);
    let mut stages = vec![StageTime {
        stage: "frame selection".into(),
        seconds: start.elapsed().as_secs_f64(),
    }];
    let start = Instant::now();
    let paths = extract_frames(video, &chosen, dir, log.path(), progress)?;
    stages.push(StageTime {
        stage: "frame extraction".into(),
        seconds: start.elapsed().as_secs_f64(),
    });
    let frames: Vec<ChosenFrame> = paths
        .iter()
        .zip(&chosen)
        .map(|(p, &frame)| ChosenFrame {
            file: p.file_name().unwrap_or_default().to_string_lossy().into(),
            frame,
            sharpness: scores[frame],
        })
        .collect();
    let summary = VideoReport {
        video: video.to_path_buf(),
        frames_in_video: scores.len(),
        frames_chosen: chosen.len(),
        mean_sharpness_chosen: frames.iter().map(|f| f.sharpness).sum::<f64>()
            / chosen.len() as f64,
        mean_sharpness_all: scores.iter().sum::<f64>() / scores.len() as f64,
    };
    Ok(VideoFrames {
        summary,
        frames,
        paths,
        stages,
    })
}

/// The sharpest frame of each of `target` equal windows of the frames (every frame when there
/// are no more than `target`), in time order; a tie goes to the earlier frame.
pub fn sharpest_per_window(scores: &[f64], target: usize) -> Vec<usize> {
    let n = scores.len();
    if n <= target {
        return (0..n).collect();
    }
    (0..target)
        .filter_map(|w| {
            let window = w * n / target..(w + 1) * n / target;
            window.reduce(|best, i| if scores[i] > scores[best] { i } else { best })
        })
        .collect()
}

/// The variance of the 4-neighbour Laplacian over the frame's inner pixels: high where edges
/// are crisp, low when motion blur or defocus smooths them.
pub fn sharpness(grey: &GrayImage) -> f64 {
    let (w, h) = (grey.width() as usize, grey.height() as usize);
    if w < 3 || h < 3 {
        return 0.0;
    }
    let px = grey.as_raw();
    let (mut sum, mut sum2) = (0.0f64, 0.0f64);
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let i = y * w + x;
            let lap = px[i - 1] as i32 + px[i + 1] as i32 + px[i - w] as i32 + px[i + w] as i32
                - 4 * px[i] as i32;
            sum += lap as f64;
            sum2 += (lap * lap) as f64;
        }
    }
    let n = ((w - 2) * (h - 2)) as f64;
    sum2 / n - (sum / n).powi(2)
}

/// `ffmpeg`/`ffprobe`, or an error saying how to install it.
fn command(program: &str) -> Command {
    let mut c = Command::new(program);
    c.stdin(Stdio::null());
    c
}

fn not_installed(program: &str, e: std::io::Error) -> Error {
    if e.kind() == std::io::ErrorKind::NotFound {
        Error::external(
            program,
            "not found on PATH: install ffmpeg (`sudo apt-get install -y ffmpeg` on Debian/Ubuntu)",
        )
    } else {
        Error::external(program, format!("cannot run it: {e}"))
    }
}

/// The last lines ffmpeg wrote, for an error.
fn tail(text: &str) -> String {
    let lines: Vec<&str> = text.lines().filter(|l| !l.trim().is_empty()).collect();
    lines[lines.len().saturating_sub(3)..].join(" / ")
}

/// The frame count the container states (for the progress bar; None when it states none), and
/// a clear error for a file ffmpeg cannot read or one without a video stream.
fn count_frames(video: &Path) -> Result<Option<u64>> {
    if !video.is_file() {
        return Err(Error::format(video, "no such file"));
    }
    let out = command("ffprobe")
        .args(["-v", "error", "-select_streams", "v:0"])
        .args(["-show_entries", "stream=codec_type,nb_frames"])
        .args(["-of", "default=noprint_wrappers=1"])
        .arg(video)
        .output()
        .map_err(|e| not_installed("ffprobe", e))?;
    let text = String::from_utf8_lossy(&out.stdout);
    if !out.status.success() {
        return Err(Error::format(
            video,
            format!(
                "ffmpeg cannot read it as a video: {}",
                tail(&String::from_utf8_lossy(&out.stderr))
            ),
        ));
    }
    if !text.lines().any(|l| l.trim() == "codec_type=video") {
        return Err(Error::format(
            video,
            "it has no video stream (ffmpeg reads it, but finds no frames to take)",
        ));
    }
    Ok(text
        .lines()
        .find_map(|l| l.trim().strip_prefix("nb_frames="))
        .and_then(|n| n.parse().ok()))
}

/// The sharpness of every frame of the video, in decoding order.
fn score_frames(
    video: &Path,
    expected: Option<u64>,
    log: &Path,
    progress: &dyn Progress,
) -> Result<Vec<f64>> {
    let errors = std::fs::File::create(log).map_err(|e| Error::io(log, e))?;
    let mut child = command("ffmpeg")
        .args(["-v", "error", "-i"])
        .arg(video)
        .args(["-map", "0:v:0", "-vsync", "passthrough", "-vf"])
        .arg(format!(
            "scale='min({SCORE_WIDTH},iw)':-1:flags=area,format=gray"
        ))
        .args(["-f", "image2pipe", "-c:v", "pgm", "-"])
        .stdout(Stdio::piped())
        .stderr(errors)
        .spawn()
        .map_err(|e| not_installed("ffmpeg", e))?;
    progress.begin("frames", expected.unwrap_or(0));
    let mut scores = Vec::new();
    let mut reader = BufReader::new(child.stdout.take().expect("piped stdout"));
    let read = loop {
        match read_pgm(&mut reader) {
            Ok(Some(frame)) => {
                scores.push(sharpness(&frame));
                progress.advance(scores.len() as u64, Detail::None);
            }
            Ok(None) => break Ok(()),
            Err(e) => break Err(e),
        }
    };
    progress.end();
    let status = child.wait().map_err(|e| Error::io(video, e))?;
    if scores.is_empty() && read.is_ok() {
        // ffmpeg fails on a stream without a frame ("cannot determine format ... after EOF").
        return Ok(scores);
    }
    if !status.success() || read.is_err() {
        let why = std::fs::read_to_string(log).unwrap_or_default();
        let why = match read {
            Err(e) if why.trim().is_empty() => e,
            _ => tail(&why),
        };
        return Err(Error::format(
            video,
            format!("ffmpeg cannot decode the video: {why}"),
        ));
    }
    Ok(scores)
}

/// One binary PGM ("P5", 8-bit) from ffmpeg's image2pipe stream; None at the end of it.
fn read_pgm(r: &mut impl BufRead) -> std::result::Result<Option<GrayImage>, String> {
    if r.fill_buf().map_err(|e| e.to_string())?.is_empty() {
        return Ok(None);
    }
    let mut fields = Vec::new();
    while fields.len() < 4 {
        let mut token = Vec::new();
        loop {
            let mut b = [0u8];
            r.read_exact(&mut b)
                .map_err(|_| "the frame stream ends inside a header".to_string())?;
            if b[0].is_ascii_whitespace() {
                if !token.is_empty() {
                    break;
                }
            } else {
                token.push(b[0]);
            }
        }
        fields.push(String::from_utf8_lossy(&token).to_string());
    }
    let num = |s: &str| {
        s.parse::<u32>()
            .map_err(|_| format!("bad PGM header field '{s}'"))
    };
    if fields[0] != "P5" || num(&fields[3])? != 255 {
        return Err(format!("unexpected frame header {fields:?}"));
    }
    let (w, h) = (num(&fields[1])?, num(&fields[2])?);
    let mut px = vec![0u8; w as usize * h as usize];
    r.read_exact(&mut px)
        .map_err(|_| "the frame stream ends inside a frame".to_string())?;
    Ok(GrayImage::from_raw(w, h, px))
}

/// Write frames `chosen` (ascending video frame indices) at full size as
/// `dir/frame_NNNNN.jpg`, numbered from 1 in time order.
fn extract_frames(
    video: &Path,
    chosen: &[usize],
    dir: &Path,
    log: &Path,
    progress: &dyn Progress,
) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let select: Vec<String> = chosen.iter().map(|i| format!("eq(n,{i})")).collect();
    let errors = std::fs::File::create(log).map_err(|e| Error::io(log, e))?;
    let mut child = command("ffmpeg")
        .args(["-v", "error", "-nostats", "-progress", "pipe:1", "-i"])
        .arg(video)
        .args(["-map", "0:v:0", "-vf"])
        .arg(format!("select='{}'", select.join("+")))
        .args(["-vsync", "passthrough", "-q:v", "2"])
        .arg(dir.join("frame_%05d.jpg"))
        .stdout(Stdio::piped())
        .stderr(errors)
        .spawn()
        .map_err(|e| not_installed("ffmpeg", e))?;
    progress.begin("extract", chosen.len() as u64);
    for line in BufReader::new(child.stdout.take().expect("piped stdout"))
        .lines()
        .map_while(|l| l.ok())
    {
        if let Some(n) = line.strip_prefix("frame=").and_then(|n| n.parse().ok()) {
            progress.advance(n, Detail::None);
        }
    }
    progress.end();
    let status = child.wait().map_err(|e| Error::io(video, e))?;
    let paths: Vec<PathBuf> = (1..=chosen.len())
        .map(|k| dir.join(format!("frame_{k:05}.jpg")))
        .collect();
    if !status.success() || !paths.iter().all(|p| p.is_file()) {
        return Err(Error::format(
            video,
            format!(
                "ffmpeg wrote {} of the {} chosen frames: {}",
                paths.iter().filter(|p| p.is_file()).count(),
                chosen.len(),
                tail(&std::fs::read_to_string(log).unwrap_or_default())
            ),
        ));
    }
    Ok(paths)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sharpest_of_each_window() {
        let scores = [1.0, 5.0, 2.0, 9.0, 3.0, 3.0, 0.0, 1.0, 4.0, 2.0];
        assert_eq!(sharpest_per_window(&scores, 5), [1, 3, 4, 7, 8]);
        assert_eq!(sharpest_per_window(&scores, 3), [1, 3, 8]);
        assert_eq!(
            sharpest_per_window(&scores, 20),
            (0..10).collect::<Vec<_>>()
        );
        assert_eq!(sharpest_per_window(&scores, 10).len(), 10);
    }

    #[test]
    fn blur_lowers_sharpness() {
        let img = GrayImage::from_fn(64, 48, |x, y| {
            image::Luma([if (x / 8 + y / 8) % 2 == 0 { 30 } else { 220 }])
        });
        let blurred = image::imageops::blur(&img, 2.0);
        let flat = GrayImage::from_pixel(64, 48, image::Luma([128]));
        let (s, b, f) = (sharpness(&img), sharpness(&blurred), sharpness(&flat));
        assert!(s > 4.0 * b && b > f, "sharp {s}, blurred {b}, flat {f}");
        assert_eq!(f, 0.0);
    }

    #[test]
    fn pgm_stream_frames() {
        let mut bytes = b"P5\n3 2\n255\n".to_vec();
        bytes.extend([1, 2, 3, 4, 5, 6]);
        bytes.extend(b"P5 1 1 255\n\x07");
        let mut r = std::io::Cursor::new(bytes);
        let a = read_pgm(&mut r).unwrap().unwrap();
        assert_eq!(
            (a.width(), a.height(), a.as_raw().clone()),
            (3, 2, vec![1, 2, 3, 4, 5, 6])
        );
        assert_eq!(read_pgm(&mut r).unwrap().unwrap().as_raw(), &vec![7]);
        assert!(read_pgm(&mut r).unwrap().is_none());
        let mut cut = std::io::Cursor::new(b"P5\n3 2\n255\n\x01".to_vec());
        assert!(read_pgm(&mut cut).is_err());
    }
}
