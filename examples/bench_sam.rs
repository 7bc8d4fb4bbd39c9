//! SAM's encoder and decoder time of our ONNX Runtime path against Python
//! onnxruntime (same version, same ONNX files, same prepared inputs, same thread count), measured
//! in one run and interleaved run by run, so that noise from other work on the machine hits both
//! sides alike. The benchmark sets up its own Python venv. Writes JSON and an SVG chart.
//!
//! cargo run --release --example bench_sam -- [--image IMG]... [--runs N] [--threads N] [--out-dir DIR]

#[path = "support/bench.rs"]
mod bench;
#[path = "support/sam.rs"]
mod sam_bench;

use bench::Stats;
use clap::Parser;
use objnerf::models::{ModelsDir, ONNXRUNTIME_VERSION};
use objnerf::sam::preprocess::encoder_input;
use objnerf::sam::{Prompts, Segmenter, SegmenterOptions};
use objnerf::util::atomic::write_bytes_atomic;
use objnerf::{Error, Result};
use sam_bench::{bench_images, chart_svg, BenchArgs, RunInfo};
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

#[derive(Clone, Debug, serde::Serialize)]
pub struct BackendTimes {
    pub name: String,
    pub load_seconds: f64,
    pub encoder: Stats,
    pub decoder: Stats,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct BenchReport {
    #[serde(flatten)]
    pub run: RunInfo,
    pub ours: BackendTimes,
    pub python: BackendTimes,
    /// ours / Python, medians.
    pub encoder_ratio: f64,
    pub decoder_ratio: f64,
    /// Median of the per-round ratios (each round runs both backends back to back, so this is
    /// the least sensitive to a machine whose load changes over the run).
    pub encoder_paired_ratio: f64,
    /// The goal: encoder median within 1.1 x Python's.
    pub encoder_goal_met: bool,
    /// Our resize + normalise + pad per image (not part of the comparison: both backends are
    /// given the same prepared tensor).
    pub ours_preprocess: Stats,
    /// Largest absolute difference between the two backends' embeddings of the first image.
    pub embedding_max_abs_diff: f64,
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

pub fn bench_sam(dir: &ModelsDir, opts: &BenchOptions) -> Result<BenchReport> {
    let runs = opts.common.runs.max(5);
    let lib = dir.require_library()?;
    let (enc, dec) = dir.require_sam()?;
    let so = SegmenterOptions {
        threads: opts.common.threads,
        disk_cache: None,
    };
    let seg = Segmenter::from_files(&lib, &enc, &dec, &so)?;
    let threads = seg.threads();

    let (images, names) = bench_images(&opts.common.images)?;

    // Both backends get the same prepared tensors; the prompt is one click at the image centre.
    let work = tempfile::Builder::new()
        .prefix("objnerf-bench-")
        .tempdir()
        .map_err(|e| Error::io(std::env::temp_dir(), e))?;
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

    // Correctness first: the two backends must compute the same embedding.
    let saved = work.path().join("py_emb0.f32");
    pyb.time(&format!("enc 0 {}", saved.display()))?;
    let py_emb = read_f32(&saved)?;
    let diff = py_emb
        .iter()
        .zip(&embs[0].0.data)
        .map(|(a, b)| (a - b).abs() as f64)
        .fold(0.0, f64::max);
    // Warm-up (untimed) for ours; Python's warm-up was the run above.
    seg.run_encoder(&inputs[0])?;
    seg.predict_allow_empty(&embs[0].0, &embs[0].1)?;
    pyb.time("dec 0")?;

    let (mut oe, mut pe, mut od, mut pd) = (vec![], vec![], vec![], vec![]);
    let mut prep = vec![];
    for r in 0..runs {
        let i = r % images.len();
        eprintln!("run {}/{runs}", r + 1);
        let t0 = std::time::Instant::now();
        std::hint::black_box(encoder_input(&images[i]));
        prep.push(t0.elapsed().as_secs_f64());
        // Alternate who goes first so that a slow phase on the machine is shared fairly.
        let ours_first = r % 2 == 0;
        for pass in 0..2 {
            if (pass == 0) == ours_first {
                oe.push(seg.run_encoder(&inputs[i])?.1);
            } else {
                pe.push(pyb.time(&format!("enc {i}"))?);
            }
        }
        for _ in 0..3 {
            for pass in 0..2 {
                if (pass == 0) == ours_first {
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

    let ours = BackendTimes {
        name: "objnerf (Rust, ort crate)".into(),
        load_seconds: seg.load_seconds,
        encoder: Stats::of(&oe),
        decoder: Stats::of(&od),
    };
    let python = BackendTimes {
        name: "Python onnxruntime".into(),
        load_seconds: py_load,
        encoder: Stats::of(&pe),
        decoder: Stats::of(&pd),
    };
    let encoder_ratio = ours.encoder.median / python.encoder.median;
    let paired: Vec<f64> = oe.iter().zip(&pe).map(|(a, b)| a / b).collect();
    let json = opts.common.out_dir.join("bench_sam.json");
    let chart = opts.common.out_dir.join("bench_sam.svg");
    let report = BenchReport {
        run: RunInfo::new(threads, names, runs),
        encoder_ratio,
        decoder_ratio: ours.decoder.median / python.decoder.median,
        encoder_paired_ratio: Stats::of(&paired).median,
        encoder_goal_met: encoder_ratio <= 1.1,
        embedding_max_abs_diff: diff,
        ours_preprocess: Stats::of(&prep),
        ours,
        python,
        json: json.clone(),
        chart: chart.clone(),
    };
    let text = serde_json::to_string_pretty(&report).expect("report serialises");
    write_bytes_atomic(&json, text.as_bytes())?;
    let svg = chart_svg(
        [
            ("encoder", &report.ours.encoder, &report.python.encoder),
            ("decoder", &report.ours.decoder, &report.python.decoder),
        ],
        ["objnerf (ort crate)", "Python onnxruntime"],
        "ours/python",
        threads,
    )
    .map_err(|e| Error::invalid(format!("chart: {e}")))?;
    write_bytes_atomic(&chart, svg.as_bytes())?;
    Ok(report)
}

fn main() -> Result<()> {
    let opts = BenchOptions::parse();
    let r = bench_sam(&ModelsDir::from_env()?, &opts)?;
    println!(
        "encoder median: ours {:.3} s, Python {:.3} s, ratio {:.3} (goal <= 1.1: {})",
        r.ours.encoder.median, r.python.encoder.median, r.encoder_ratio, r.encoder_goal_met
    );
    println!(
        "encoder paired ratio (median of per-round ours/Python): {:.3}",
        r.encoder_paired_ratio
    );
    println!(
        "decoder median: ours {:.1} ms, Python {:.1} ms, ratio {:.3}",
        r.ours.decoder.median * 1e3,
        r.python.decoder.median * 1e3,
        r.decoder_ratio
    );
    println!("wrote {} and {}", r.json.display(), r.chart.display());
    Ok(())
}
