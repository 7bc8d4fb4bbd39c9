//! `scripts/ray_batch.py` (issue 57) on the 8-job manifest of `tests/batch.rs`, on a local Ray
//! head (loopback only), one Ray worker killed mid-job. Opt-in (Ray's install and start take
//! minutes): `bash scripts/setup-ray && cargo test --release --test batch_ray -- --ignored --nocapture`.

mod batch_jobs;
mod common;

use batch_jobs::{batch, check_outputs, eight_job_manifest, files, read_json};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::process::Command;

/// Every process: (pid, parent pid, command line).
fn processes() -> Vec<(i32, i32, Vec<String>)> {
    let mut out = Vec::new();
    for e in std::fs::read_dir("/proc").unwrap().flatten() {
        let Ok(pid) = e.file_name().to_string_lossy().parse::<i32>() else {
            continue;
        };
        let (Ok(stat), Ok(cmd)) = (
            std::fs::read_to_string(e.path().join("stat")),
            std::fs::read(e.path().join("cmdline")),
        ) else {
            continue;
        };
        // "pid (comm) state ppid ...": comm may hold spaces, so read after its last ')'.
        let after = &stat[stat.rfind(')').unwrap() + 2..];
        let ppid = after.split(' ').nth(1).unwrap().parse().unwrap();
        let args = cmd
            .split(|&b| b == 0)
            .filter(|a| !a.is_empty())
            .map(|a| String::from_utf8_lossy(a).to_string())
            .collect();
        out.push((pid, ppid, args));
    }
    out
}

/// The resident memory of `roots` and all their descendants, KiB.
fn tree_rss_kib(roots: &[i32]) -> u64 {
    let ps = processes();
    let mut tree: Vec<i32> = roots.to_vec();
    let mut i = 0;
    while i < tree.len() {
        let p = tree[i];
        tree.extend(ps.iter().filter(|q| q.1 == p).map(|q| q.0));
        i += 1;
    }
    tree.iter()
        .filter_map(|p| std::fs::read_to_string(format!("/proc/{p}/status")).ok())
        .filter_map(|s| {
            let l = s.lines().find(|l| l.starts_with("VmRSS:"))?;
            l.split_whitespace().nth(1)?.parse::<u64>().ok()
        })
        .sum()
}

/// Alive and not a zombie.
fn running(pid: i32) -> bool {
    std::fs::read_to_string(format!("/proc/{pid}/stat"))
        .map(|s| !s[s.rfind(')').unwrap() + 2..].starts_with('Z'))
        .unwrap_or(false)
}

/// A Ray head (`ray start --head --block`) in a network namespace of its own that has only the
/// loopback interface (`unshare --net`: Ray would otherwise register and listen on the
/// machine's address too), in a process group of its own, ended with the group when dropped.
struct RayHead {
    child: std::process::Child,
    address: String,
    temp: PathBuf,
}

impl RayHead {
    fn start(venv: &Path, log: &Path) -> RayHead {
        use std::os::unix::process::CommandExt;
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let temp = format!("/tmp/ray-objnerf-{}", std::process::id());
        // `unshare` execs the shell, which execs Ray: the child's pid is the head's.
        let child = Command::new("unshare")
            .args([
                "--net",
                "sh",
                "-c",
                "ip link set lo up && exec \"$0\" \"$@\"",
            ])
            .arg(venv.join("ray"))
            .args(["start", "--head", "--block", "--node-ip-address=127.0.0.1"])
            .arg(format!("--port={port}"))
            .arg(format!("--temp-dir={temp}"))
            .args(["--num-cpus=2", "--object-store-memory=200000000"])
            .args(["--include-dashboard=false", "--disable-usage-stats"])
            .env("RAY_USAGE_STATS_ENABLED", "0")
            .stdout(std::fs::File::create(log).unwrap())
            .stderr(std::fs::File::create(log.with_extension("err")).unwrap())
            .process_group(0)
            .spawn()
            .expect("unshare (util-linux) runs the Ray head; the test runs as root, as CI does");
        let head = RayHead {
            child,
            address: format!("127.0.0.1:{port}"),
            temp: PathBuf::from(temp),
        };
        let t0 = std::time::Instant::now();
        while !std::fs::read_to_string(log)
            .unwrap_or_default()
            .contains("block forever")
        {
            assert!(
                t0.elapsed().as_secs() < 120,
                "the Ray head did not start: see {}",
                log.display()
            );
            std::thread::sleep(std::time::Duration::from_millis(200));
        }
        let net = std::fs::read_to_string(format!("/proc/{}/net/dev", head.child.id())).unwrap();
        let interfaces: Vec<&str> = net
            .lines()
            .skip(2)
            .filter_map(|l| l.split(':').next())
            .map(str::trim)
            .collect();
        assert_eq!(interfaces, ["lo"], "the Ray head sees more than loopback");
        head
    }

    /// A command in the head's network namespace (`nsenter`).
    fn command(&self, program: &Path) -> Command {
        let mut c = Command::new("nsenter");
        c.arg(format!("--net=/proc/{}/ns/net", self.child.id()))
            .arg("--")
            .arg(program);
        c
    }
}

impl Drop for RayHead {
    fn drop(&mut self) {
        let group = -(self.child.id() as i32);
        // SAFETY: signals to the process group this test started.
        unsafe { libc::kill(group, libc::SIGTERM) };
        let _ = self.child.wait();
        std::thread::sleep(std::time::Duration::from_secs(3));
        unsafe { libc::kill(group, libc::SIGKILL) };
        let _ = std::fs::remove_dir_all(&self.temp);
    }
}

/// A JSON file without what depends on the clock or the machine's state: times, rates, peak
/// memory, and SAM encoder runs (the embedding cache was warm for the second run).
fn without_timings(v: &mut Value) {
    match v {
        Value::Object(m) => {
            m.retain(|k, _| {
                !(k.contains("second")
                    || k.contains("peak_rss")
                    || k == "timings"
                    || k.ends_with("encoder_runs"))
            });
            m.values_mut().for_each(without_timings);
        }
        Value::Array(a) => a.iter_mut().for_each(without_timings),
        _ => {}
    }
}

/// `text` with every number replaced by `#`.
fn without_numbers(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut in_number = false;
    for c in text.chars() {
        let digit = c.is_ascii_digit() || (in_number && c == '.');
        if digit && !in_number {
            out.push('#');
        } else if !digit {
            out.push(c);
        }
        in_number = digit;
    }
    out
}

/// A model file's header (timings dropped from its notes) and its arrays, byte for byte.
fn model_parts(path: &Path) -> (Value, Vec<u8>) {
    let b = std::fs::read(path).unwrap();
    let i = b.iter().position(|&c| c == b'{').unwrap();
    let n = u64::from_le_bytes(b[i - 8..i].try_into().unwrap()) as usize;
    let mut header: Value = serde_json::from_slice(&b[i..i + n]).unwrap();
    without_timings(&mut header);
    (header, b[i + n..].to_vec())
}

/// Each job's folder in `a` and `b` holds the same files with the same contents, but for times.
fn same_outputs(a: &Path, b: &Path, ids: &[&str]) {
    for id in ids {
        let (fa, fb) = (files(&a.join(id)), files(&b.join(id)));
        assert_eq!(
            fa.keys().collect::<Vec<_>>(),
            fb.keys().collect::<Vec<_>>(),
            "{id}"
        );
        for rel in fa.keys() {
            let (pa, pb) = (a.join(id).join(rel), b.join(id).join(rel));
            let what = format!("{id}/{}", rel.display());
            match rel.extension().and_then(|e| e.to_str()) {
                Some("json") => {
                    let (mut ja, mut jb) = (read_json(&pa), read_json(&pb));
                    without_timings(&mut ja);
                    without_timings(&mut jb);
                    assert_eq!(ja, jb, "{what}");
                }
                Some("objf") => assert!(model_parts(&pa) == model_parts(&pb), "{what}"),
                // The page shows report.json (compared above) with its times: the same page
                // but for its numbers.
                Some("html") => assert_eq!(
                    without_numbers(&std::fs::read_to_string(&pa).unwrap()),
                    without_numbers(&std::fs::read_to_string(&pb).unwrap()),
                    "{what}"
                ),
                _ => assert!(
                    std::fs::read(&pa).unwrap() == std::fs::read(&pb).unwrap(),
                    "{what}"
                ),
            }
        }
    }
}

/// The 8-job manifest through `scripts/ray_batch.py` on a local Ray head (loopback only), with
/// the Ray worker running one job killed while the job is in its second stage: Ray retries the
/// task, the killed attempt's processes end with their worker, every job finishes once, and the
/// outputs are the local run's but for times.
#[test]
#[ignore = "Ray: bash scripts/setup-ray && cargo test --release --test batch_ray -- --ignored (README)"]
fn ray_runs_the_manifest_and_a_killed_worker_is_retried() {
    if !common::sam_installed() {
        return;
    }
    let venv = common::repo_root().join(".venv-ray/bin");
    assert!(
        venv.join("python").is_file(),
        "no .venv-ray: run bash scripts/setup-ray"
    );
    let dir = tempfile::tempdir().unwrap();
    let manifest = eight_job_manifest(dir.path());
    let local = dir.path().join("local");
    let t_local = std::time::Instant::now();
    assert!(batch(&[&manifest], &["--out", local.to_str().unwrap()])
        .status
        .success());
    println!("local run: {:.0} s wall", t_local.elapsed().as_secs_f64());

    let head = RayHead::start(&venv, &dir.path().join("ray_head.log"));
    let out = dir.path().join("ray");
    let t0 = std::time::Instant::now();
    let mut driver = head
        .command(&venv.join("python"))
        .arg(common::repo_root().join("scripts/ray_batch.py"))
        .arg(&manifest)
        .arg("--out")
        .arg(&out)
        .args(["--address", &head.address])
        .arg("--objnerf")
        .arg(common::objnerf_bin())
        .env("RAY_USAGE_STATS_ENABLED", "0")
        .spawn()
        .unwrap();

    // The job mug_s1 in its second stage (remove): its supervisor `objnerf batch --job mug_s1`,
    // the stage under it, and the Ray worker above it.
    let out_arg = out.display().to_string();
    let (worker, supervisor, stage) = loop {
        let ps = processes();
        let found = ps.iter().find_map(|(pid, ppid, args)| {
            let sup = args.iter().any(|a| a == "--job")
                && args.iter().any(|a| a == "mug_s1")
                && args.contains(&out_arg);
            let stage = ps
                .iter()
                .find(|(_, parent, a)| parent == pid && a.get(1).is_some_and(|s| s == "remove"));
            (sup && stage.is_some()).then(|| (*ppid, *pid, stage.unwrap().0))
        });
        if let Some(f) = found {
            break f;
        }
        assert!(
            driver.try_wait().unwrap().is_none(),
            "the driver ended before mug_s1 was seen removing"
        );
        assert!(
            t0.elapsed().as_secs() < 600,
            "mug_s1 never reached its remove stage"
        );
        std::thread::sleep(std::time::Duration::from_millis(50));
    };
    let worker_cmd = processes()
        .into_iter()
        .find(|p| p.0 == worker)
        .map(|p| p.2.join(" "));
    println!(
        "killing Ray worker {worker} ({worker_cmd:?}), which runs mug_s1's remove (pid {stage})"
    );
    // SAFETY: a process of the Ray head this test started.
    unsafe { libc::kill(worker, libc::SIGKILL) };
    let killed = std::time::Instant::now();
    while running(supervisor) || running(stage) {
        assert!(
            killed.elapsed().as_secs() < 10,
            "the killed worker's job processes live on (supervisor {supervisor}, stage {stage})"
        );
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    // Measured, not asserted: the Ray run's memory, every process of the head and the driver
    // (Ray's own and the jobs') summed, sampled every 200 ms.
    let roots = [head.child.id() as i32, driver.id() as i32];
    let mut peak_kib = 0;
    let status = loop {
        if let Some(s) = driver.try_wait().unwrap() {
            break s;
        }
        peak_kib = peak_kib.max(tree_rss_kib(&roots));
        std::thread::sleep(std::time::Duration::from_millis(200));
    };
    println!(
        "ray run: {:.0} s wall, peak {} MiB summed over Ray's and the jobs' processes",
        t0.elapsed().as_secs_f64(),
        peak_kib >> 10
    );
    drop(head);
    assert!(status.success(), "the Ray driver failed");

    let summary = read_json(&out.join("summary.json"));
    assert_eq!(summary["counts"], json!({"ok": 8}), "{summary}");
    check_outputs(&out, &summary);
    // mug_s1 ran again from its first stage after the kill, and once: its log is the retry's.
    let log = std::fs::read_to_string(out.join("logs/mug_s1.log")).unwrap();
    assert_eq!(log.matches("$ objnerf extract").count(), 1, "{log}");
    assert_eq!(log.matches("$ objnerf remove").count(), 1, "{log}");
    let local_summary = read_json(&local.join("summary.json"));
    for (l, r) in local_summary["jobs"]
        .as_array()
        .unwrap()
        .iter()
        .zip(summary["jobs"].as_array().unwrap())
    {
        assert_eq!(l["scores"], r["scores"], "{}", l["id"]);
    }
    let ids: Vec<&str> = summary["jobs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|j| j["id"].as_str().unwrap())
        .collect();
    same_outputs(&local, &out, &ids);
}
