#!/usr/bin/env python3
"""Gather what scripts/quality measured into quality.json and quality.md.

    python3 scripts/quality_report.py WORK_DIR OUT_DIR

WORK_DIR holds runs.jsonl (one line per test run: test, command, pass, seconds, peak RSS) and
figures.jsonl (one line per figure a test recorded through tests/common's `figure`).
"""
import json
import os
import platform
import subprocess
import sys
from datetime import datetime, timezone
from pathlib import Path


def lines(path):
    p = Path(path)
    return [json.loads(x) for x in p.read_text().splitlines() if x.strip()] if p.exists() else []


def machine():
    model = ""
    try:
        for line in subprocess.run(["lscpu"], capture_output=True, text=True).stdout.splitlines():
            if line.startswith("Model name:"):
                model = line.split(":", 1)[1].strip()
    except OSError:
        pass
    mem = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30
    return {"cpu": model, "cores": os.cpu_count(), "memory_gib": round(mem, 1),
            "os": platform.platform()}


def main():
    work, out = Path(sys.argv[1]), Path(sys.argv[2])
    runs, figures = lines(work / "runs.jsonl"), lines(work / "figures.jsonl")
    for r in runs:
        name = r["test"].split("::", 1)[1]
        r["figures"] = [
            {k: f[k] for k in ("figure", "value", "floor", "higher_is_better", "pass")}
            for f in figures if f["test"] == name
        ]
    # Each record names the commit it measured (older records without one: the report's).
    head = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True).stdout.strip()
    for r in runs:
        r.setdefault("commit", head)
        r.setdefault("dirty", False)
    commits = sorted({r["commit"] for r in runs}, key=lambda c: -sum(r["commit"] == c for r in runs))
    commit = commits[0] if commits else head
    dirty = any(r["dirty"] for r in runs)
    skipped = (work / "skipped.txt").read_text().splitlines() if (work / "skipped.txt").exists() else []
    report = {
        "command": "bash scripts/quality", "git_commit": commit, "git_commits": commits,
        "dirty": dirty,
        "date": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "machine": machine(), "load_average_end": os.getloadavg()[0],
        "passed": sum(r["pass"] for r in runs), "failed": sum(not r["pass"] for r in runs),
        "skipped": skipped, "runs": runs,
    }
    tmp = out / "quality.json.tmp"
    tmp.write_text(json.dumps(report, indent=2) + "\n")
    tmp.replace(out / "quality.json")
    md = [f"# Quality run\n\n`bash scripts/quality` at {', '.join(c[:12] for c in commits)}"
          f"{' (dirty)' if dirty else ''} (each test's commit in quality.json), "
          f"{report['date']}, {report['machine']['cpu']} ({report['machine']['cores']} cores); "
          f"{report['passed']} passed, {report['failed']} failed.\n",
          "| test | figure | value | floor | pass | s | MiB |", "|---|---|---|---|---|---|---|"]
    for r in runs:
        rows = r["figures"] or [{"figure": "-", "value": None, "floor": None, "pass": r["pass"]}]
        for f in rows:
            v = "-" if f["value"] is None else f"{f['value']:.3f}"
            fl = "-" if f["floor"] is None else f"{'>=' if f.get('higher_is_better', True) else '<='} {f['floor']}"
            md.append(f"| {r['test']} | {f['figure']} | {v} | {fl} | {'yes' if f['pass'] and r['pass'] else 'NO'} "
                      f"| {r['seconds']:.0f} | {r['peak_rss_mib']} |")
    for r in runs:
        if not r["pass"]:
            md.append(f"\n### {r['test']} failed\n\n```\n" + "\n".join(r["tail"]) + "\n```")
    if skipped:
        md.append("\n## Skipped\n\n" + "\n".join(f"- {s}" for s in skipped))
    tmp = out / "quality.md.tmp"
    tmp.write_text("\n".join(md) + "\n")
    tmp.replace(out / "quality.md")
    print(f"{report['passed']} passed, {report['failed']} failed -> {out}/quality.json")


if __name__ == "__main__":
    main()
