//! SAM's encoders against Python onnxruntime's fp32 (issue 58): our fp32 and int8 encoders (and,
//! for the chart of time against mask IoU, the two halves of int8: int8 Linear layers alone and
//! fused attention alone), each timed in the same run, interleaved round by round with the Python
//! peer on the same prepared tensors, so that noise from other work on the machine hits every side
//! alike; the decoder against Python's; and every encoder's masks against fp32's on the demo,
//! lego and fox views (support/sam_views.rs). The benchmark sets up its own Python venv. Writes
//! JSON and an SVG chart.
//!
//! cargo run --release --example bench_sam -- [--image IMG]... [--runs N] [--threads N] [--out-dir DIR]

#[path = "support/bench.rs"]
mod bench;
#[path = "support/sam.rs"]
mod sam_bench;
#[path = "support/sam_views.rs"]
mod sam_views;

use bench::Stats;
use clap::Parser;
use objnerf::models::{ModelsDir, ONNXRUNTIME_VERSION};
use objnerf::sam::convert::encoder::{build_variant, Variant};
use objnerf::sam::convert::torch::StateDict;
use objnerf::sam::preprocess::encoder_input;
use objnerf::sam::{Precision, Prompts, Segmenter, SegmenterOptions};
use objnerf::util::atomic::write_bytes_atomic;
use objnerf::util::chart::{palette, svg, Layer, Mark, Panel};
use objnerf::util::mem::peak_rss_mib;
use objnerf::{Error, Result};
use prost::Message;
use sam_bench::{bench_images, BenchArgs, RunInfo};
use sam_views::{compare, iou_cases, masks, mean_iou_vs_truth, perturbed, IouSummary};
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};

const PY_BENCH: &str = include_str!("bench_sam.py");

#[derive(Parser, Debug)]
pub struct BenchOptions {
    #[command(flatten)]
    pub common: BenchArgs,
    /// The venv to use or create; default `<models dir>/venvs/bench-onnxruntime-<version>`.
    #[arg(long)]
    pub venv: Option<PathBuf>,
}

/// One of our encoders.
#[derive(Clone, Debug, serde::Serialize)]
pub struct EncoderRow {
    pub name: String,
    pub variant: Variant,
    /// Where it came from: the installed file, or written by this run from the checkpoint.
    pub file: PathBuf,
    pub encoder: Stats,
    /// Median over rounds of (this encoder / Python fp32), each round's pair run back to back.
    pub paired_ratio_to_python: f64,
    /// Its masks against our fp32 encoder's, one click per case.
    pub iou_vs_fp32: IouSummary,
    /// Its masks against the truth, over the demo's clicks (whose true masks are known): fp32's
    /// own masks are not the truth, and where the two disagree either may be the right one.
    pub demo_iou_vs_truth: f64,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct BenchReport {
    #[serde(flatten)]
    pub run: RunInfo,
    /// fp32, int8, then the chart's two halves of int8.
    pub encoders: Vec<EncoderRow>,
    /// The peer: Python onnxruntime on our fp32 encoder file.
    pub python_fp32_encoder: Stats,
    pub python_load_seconds: f64,
    pub decoder: Stats,
    pub python_decoder: Stats,
    pub decoder_ratio: f64,
    /// The goal: the int8 encoder at most 0.5 x Python fp32's time (paired) with mean mask
    /// IoU >= 0.98 against fp32's.
    pub int8_goal_met: bool,
    /// fp32's masks on the same images moved by at most one grey level (seeded): how far the masks
    /// of these clicks move under a change no one could see, the floor for the rows above.
    pub fp32_one_grey_level: IouSummary,
    /// Largest absolute difference between our fp32 and Python's embeddings of the first image.
    pub embedding_max_abs_diff: f64,
    /// This process's peak resident memory (every encoder session loaded at once).
    pub peak_rss_mib: u64,
    /// The machine's load over the last minute, at the start and at the end.
    pub load_average: [String; 2],
    pub json: PathBuf,
    pub chart: PathBuf,
}

/// The venv's interpreter, creating the venv (with onnxruntime, numpy, pillow) if it is missing
/// or broken.
pub fn ensure_venv(venv: &Path) -> Result<PathBuf> {
    let check = format!(
        "import onnxruntime, numpy; assert onnxruntime.__version__ == '{ONNXRUNTIME_VERSION}'"
    );
    bench::ensure_venv(
        venv,
        &check,
        &[
            &format!("onnxruntime=={ONNXRUNTIME_VERSION}"),
            "numpy",
            "pillow",
        ],
    )
}

/// The Python side: a process that loads both sessions once and then times one run per command.
struct PyBench {
    child: Child,
    stdin: ChildStdin,
    stdout: BufReader<ChildStdout>,
}

impl PyBench {
    fn start(
        py: &Path,
        script: &Path,
        dir: &ModelsDir,
        threads: usize,
        work: &Path,
    ) -> Result<(Self, f64)> {
        let mut child = Command::new(py)
            .arg(script)
            .arg(dir.encoder())
            .arg(dir.decoder())
            .arg(threads.to_string())
            .arg(work)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .map_err(|e| Error::external("python benchmark", e.to_string()))?;
        let stdin = child.stdin.take().expect("piped");
        let stdout = BufReader::new(child.stdout.take().expect("piped"));
        let mut me = PyBench {
            child,
            stdin,
            stdout,
        };
        let ready = me.read()?;
        Ok((me, ready["load_seconds"].as_f64().unwrap_or(f64::NAN)))
    }

    fn read(&mut self) -> Result<serde_json::Value> {
        let mut line = String::new();
        self.stdout
            .read_line(&mut line)
            .map_err(|e| Error::external("python benchmark", e.to_string()))?;
        serde_json::from_str(&line).map_err(|_| {
            Error::external(
                "python benchmark",
                format!("unexpected reply {line:?} (see its error output above)"),
            )
        })
    }

    fn time(&mut self, cmd: &str) -> Result<f64> {
        writeln!(self.stdin, "{cmd}")
            .and_then(|_| self.stdin.flush())
            .map_err(|e| Error::external("python benchmark", e.to_string()))?;
        let v = self.read()?;
        v["seconds"]
            .as_f64()
            .ok_or_else(|| Error::external("python benchmark", format!("bad reply {v}")))
    }
}

impl Drop for PyBench {
    fn drop(&mut self) {
        let _ = writeln!(self.stdin, "quit");
        let _ = self.child.wait();
    }
}

fn write_f32(path: &Path, v: &[f32]) -> Result<()> {
    let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
    std::fs::write(path, bytes).map_err(|e| Error::io(path, e))
}

fn read_f32(path: &Path) -> Result<Vec<f32>> {
    let b = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    Ok(b.chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect())
}

fn load_avg() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_default()
}

/// Our encoders: the installed fp32 and int8 files, and the chart's other variants written from
/// the checkpoint into `work`.
fn encoders(dir: &ModelsDir, work: &Path) -> Result<Vec<(String, Variant, PathBuf)>> {
    let (fp32, _) = dir.require_sam_at(Precision::Fp32)?;
    let (int8, _) = dir.require_sam_at(Precision::Int8)?;
    let mut out = vec![
        ("fp32".to_string(), Variant::FP32, fp32),
        ("int8".to_string(), Variant::INT8, int8),
    ];
    let sd = StateDict::load(&dir.checkpoint())?;
    for (name, v) in [
        (
            "int8, signed weights",
            Variant {
                unsigned_weights: false,
                ..Variant::INT8
            },
        ),
        (
            "int8 Linear only",
            Variant {
                fused_attention: false,
                ..Variant::INT8
            },
        ),
        (
            "fused attention only",
            Variant {
                fused_attention: true,
                ..Variant::FP32
            },
        ),
    ] {
        let path = work.join(format!("{}.onnx", name.replace(' ', "_")));
        write_bytes_atomic(&path, &build_variant(&sd, v)?.encode_to_vec())?;
        out.push((name.to_string(), v, path));
    }
    Ok(out)
}

pub fn bench_sam(dir: &ModelsDir, opts: &BenchOptions) -> Result<BenchReport> {
    let load_start = load_avg();
    let runs = opts.common.runs.max(5);
    let lib = dir.require_library()?;
    let so = SegmenterOptions {
        threads: opts.common.threads,
        disk_cache: None,
    };
    let work = tempfile::Builder::new()
        .prefix("objnerf-bench-")
        .tempdir()
        .map_err(|e| Error::io(std::env::temp_dir(), e))?;
    let list = encoders(dir, work.path())?;
    let segs: Vec<Segmenter> = list
        .iter()
        .map(|(_, _, enc)| Segmenter::from_files(&lib, enc, &dir.decoder(), &so))
        .collect::<Result<_>>()?;
    let seg = &segs[0];
    let threads = seg.threads();

    let (images, names) = bench_images(&opts.common.images)?;

    // Every side gets the same prepared tensors; the prompt is one click at the image centre.
    let mut inputs = Vec::new();
    let mut embs = Vec::new();
    let mut spec = Vec::new();
    for (i, img) in images.iter().enumerate() {
        let (t, _) = encoder_input(img);
        write_f32(&work.path().join(format!("img{i}.f32")), &t)?;
        inputs.push(t);
        let emb = seg.embed(img)?;
        write_f32(&work.path().join(format!("emb{i}.f32")), &emb.data)?;
        let prompts = Prompts::click(img.width() as f32 / 2.0, img.height() as f32 / 2.0);
        let (coords, labels) = prompts.decoder_inputs(emb.scale);
        spec.push(serde_json::json!({
            "coords": coords, "labels": labels, "h": img.height(), "w": img.width()
        }));
        embs.push((emb, prompts));
    }
    let spec_path = work.path().join("spec.json");
    std::fs::write(&spec_path, serde_json::to_vec(&spec).expect("json"))
        .map_err(|e| Error::io(&spec_path, e))?;
    let script = work.path().join("bench_sam.py");
    std::fs::write(&script, PY_BENCH).map_err(|e| Error::io(&script, e))?;

    let venv = opts.venv.clone().unwrap_or_else(|| {
        dir.root
            .join("venvs")
            .join(format!("bench-onnxruntime-{ONNXRUNTIME_VERSION}"))
    });
    let py = ensure_venv(&venv)?;
    let (mut pyb, py_load) = PyBench::start(&py, &script, dir, threads, work.path())?;

    // Correctness first: our fp32 and Python's must compute the same embedding.
    let saved = work.path().join("py_emb0.f32");
    pyb.time(&format!("enc 0 {}", saved.display()))?;
    let py_emb = read_f32(&saved)?;
    let diff = py_emb
        .iter()
        .zip(&embs[0].0.data)
        .map(|(a, b)| (a - b).abs() as f64)
        .fold(0.0, f64::max);
    // Warm-up (untimed) for ours; Python's warm-up was the run above.
    for s in &segs {
        s.run_encoder(&inputs[0])?;
    }
    seg.predict_allow_empty(&embs[0].0, &embs[0].1)?;
    pyb.time("dec 0")?;

    // Each round runs every encoder once (ours, then Python as one more side), starting from a
    // different side each round so that a slow phase on the machine is shared fairly.
    let sides = segs.len() + 1;
    let mut enc_times = vec![Vec::new(); sides];
    let (mut od, mut pd) = (vec![], vec![]);
    for r in 0..runs {
        let i = r % images.len();
        eprintln!("run {}/{runs}", r + 1);
        for k in 0..sides {
            let side = (k + r) % sides;
            let t = match segs.get(side) {
                Some(s) => s.run_encoder(&inputs[i])?.1,
                None => pyb.time(&format!("enc {i}"))?,
            };
            enc_times[side].push(t);
        }
        for _ in 0..3 {
            for pass in 0..2 {
                if (pass + r) % 2 == 0 {
                    od.push(
                        seg.predict_allow_empty(&embs[i].0, &embs[i].1)?
                            .decoder_seconds,
                    );
                } else {
                    pd.push(pyb.time(&format!("dec {i}"))?);
                }
            }
        }
    }
    drop(pyb);

    // Masks against fp32's on the demo, lego and fox views.
    eprintln!("masks on the demo, lego and fox views ...");
    let cases = iou_cases(work.path())?;
    let reference = masks(seg, &cases)?;
    let python = &enc_times[segs.len()];
    let mut rows = Vec::new();
    for (k, ((name, variant, file), s)) in list.into_iter().zip(&segs).enumerate() {
        let got = if k == 0 {
            reference.clone()
        } else {
            masks(s, &cases)?
        };
        let paired: Vec<f64> = enc_times[k]
            .iter()
            .zip(python)
            .map(|(a, b)| a / b)
            .collect();
        rows.push(EncoderRow {
            name,
            variant,
            file,
            encoder: Stats::of(&enc_times[k]),
            paired_ratio_to_python: Stats::of(&paired).median,
            iou_vs_fp32: compare(&cases, &reference, &got),
            demo_iou_vs_truth: mean_iou_vs_truth(&cases, &got),
        });
    }
    let fp32_one_grey_level = compare(&cases, &reference, &masks(seg, &perturbed(&cases, 58))?);
    let json = opts.common.out_dir.join("bench_sam.json");
    let chart = opts.common.out_dir.join("bench_sam.svg");
    let (decoder, python_decoder) = (Stats::of(&od), Stats::of(&pd));
    let int8 = &rows[1];
    let report = BenchReport {
        run: RunInfo::new(threads, names, runs),
        int8_goal_met: int8.paired_ratio_to_python <= 0.5 && int8.iou_vs_fp32.mean >= 0.98,
        python_fp32_encoder: Stats::of(python),
        python_load_seconds: py_load,
        decoder_ratio: decoder.median / python_decoder.median,
        decoder,
        python_decoder,
        encoders: rows,
        fp32_one_grey_level,
        embedding_max_abs_diff: diff,
        peak_rss_mib: peak_rss_mib(),
        load_average: [load_start, load_avg()],
        json: json.clone(),
        chart: chart.clone(),
    };
    let text = serde_json::to_string_pretty(&report).expect("report serialises");
    write_bytes_atomic(&json, text.as_bytes())?;
    let svg = chart_svg(&report, threads).map_err(|e| Error::invalid(format!("chart: {e}")))?;
    write_bytes_atomic(&chart, svg.as_bytes())?;
    Ok(report)
}

/// Left: every timed encoder run of fp32, int8 and the Python peer, medians dashed. Right: each
/// encoder's time (paired ratio to the peer) against its masks' mean IoU with fp32's (worst as
/// a smaller mark).
fn chart_svg(r: &BenchReport, threads: usize) -> objnerf::util::chart::ChartResult<String> {
    let mut runs = Vec::new();
    let named: Vec<(&str, &Stats)> = vec![
        ("ours fp32", &r.encoders[0].encoder),
        ("ours int8", &r.encoders[1].encoder),
        ("Python onnxruntime fp32", &r.python_fp32_encoder),
    ];
    for (k, (name, st)) in named.iter().enumerate() {
        let pts: Vec<(f64, f64)> = st
            .runs
            .iter()
            .enumerate()
            .map(|(i, s)| (i as f64 + 1.0, s * 1e3))
            .collect();
        let x = 0.0..pts.len() as f64 + 1.0;
        runs.push(Layer::new(*name, palette(k), pts));
        runs.push(Layer::level(None, palette(k), st.median * 1e3, &x));
    }
    let mut left = Panel::fitted(
        &format!(
            "encoder, {threads} threads: int8/Python {:.2} paired",
            r.encoders[1].paired_ratio_to_python
        ),
        "run",
        "ms",
        runs,
    );
    left.y.start = 0.0;
    let mut pts = Vec::new();
    for (k, e) in r.encoders.iter().enumerate() {
        let x = e.paired_ratio_to_python;
        pts.push(
            Layer::new(e.name.clone(), palette(k), vec![(x, e.iou_vs_fp32.mean)])
                .mark(Mark::Points(6)),
        );
        pts.push(Layer {
            name: None,
            colour: palette(k),
            points: vec![(x, e.iou_vs_fp32.worst)],
            mark: Mark::Points(3),
        });
    }
    let floor = &r.fp32_one_grey_level;
    let across = 0.0..1.1;
    pts.push(Layer::level(
        Some("fp32, image +-1 grey level (mean; worst)"),
        palette(r.encoders.len()),
        floor.mean,
        &across,
    ));
    pts.push(Layer::level(
        None,
        palette(r.encoders.len()),
        floor.worst,
        &across,
    ));
    let mut right = Panel::fitted(
        "time against masks (big: mean IoU, small: worst)",
        "encoder time / Python fp32 (paired)",
        "mask IoU vs fp32",
        pts,
    );
    right.x.start = 0.0;
    right.x.end = right.x.end.max(1.1);
    // The points sit right of 0.75 and from the worst IoU up: the legend goes where none are.
    right.legend = objnerf::util::chart::SeriesLabelPosition::MiddleLeft;
    svg((1000, 420), 1, &[left, right])
}

fn main() -> Result<()> {
    let opts = BenchOptions::parse();
    let r = bench_sam(&ModelsDir::from_env()?, &opts)?;
    println!(
        "Python onnxruntime fp32 encoder: median {:.3} s",
        r.python_fp32_encoder.median
    );
    for e in &r.encoders {
        println!(
            "{:<22} median {:.3} s, paired ratio to Python fp32 {:.3}; mask IoU vs fp32 mean {:.4}, worst {:.4} ({}); demo vs truth {:.4}",
            e.name,
            e.encoder.median,
            e.paired_ratio_to_python,
            e.iou_vs_fp32.mean,
            e.iou_vs_fp32.worst,
            e.iou_vs_fp32.worst_case,
            e.demo_iou_vs_truth
        );
    }
    let floor = &r.fp32_one_grey_level;
    println!(
        "fp32 on the images moved by <= 1 grey level: mask IoU mean {:.4}, worst {:.4} ({})",
        floor.mean, floor.worst, floor.worst_case
    );
    println!(
        "decoder median: ours {:.1} ms, Python {:.1} ms, ratio {:.3}",
        r.decoder.median * 1e3,
        r.python_decoder.median * 1e3,
        r.decoder_ratio
    );
    println!(
        "goal (int8 <= 0.5 x Python fp32, mean IoU >= 0.98): {}; peak RSS {} MiB",
        r.int8_goal_met, r.peak_rss_mib
    );
    println!("wrote {} and {}", r.json.display(), r.chart.display());
    Ok(())
}
