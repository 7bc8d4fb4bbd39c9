#!/usr/bin/env python3
"""Run an `objnerf batch` manifest on Ray: one Ray task a job.

Each task runs `objnerf batch MANIFEST --out OUT --job ID`, the same per-job entry point the
local runner uses, so a job writes the same OUT/<id>/ however it is run. Ray is the engine: it
places the tasks by their resources (the job's "resources" in the manifest, else --cpus and
--memory-mb) and retries a task whose worker died (--max-retries); nothing here schedules,
queues or retries. At the end `objnerf batch MANIFEST --out OUT --summary` gathers the jobs'
records into OUT/summary.json and prints the table.

    .venv-ray/bin/python scripts/ray_batch.py jobs.jsonl --out runs/batch          # a local Ray
    .venv-ray/bin/python scripts/ray_batch.py jobs.jsonl --out /shared/runs/batch --address auto

On a cluster the objnerf binary, the manifest, its scenes and OUT must be at the same paths on
every node (a shared filesystem); docs/batch.md.
"""

import argparse
import json
import os
import subprocess
import sys
import time

import ray


def run_job(objnerf, manifest, out, job_id):
    """One job, in a Ray worker: its record (what `objnerf batch --job` prints)."""
    p = subprocess.run(
        [objnerf, "batch", manifest, "--out", out, "--job", job_id],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    lines = p.stdout.strip().splitlines()
    try:
        return json.loads(lines[-1])
    except (IndexError, json.JSONDecodeError):
        # No record: the job's supervisor itself did not finish (its stderr says why).
        raise RuntimeError(
            f"objnerf batch --job {job_id} exited {p.returncode} without a record: {p.stderr.strip()}"
        )


def check(objnerf, manifest):
    """The manifest's jobs as objnerf reads them (every line checked before anything runs)."""
    p = subprocess.run(
        [objnerf, "batch", manifest, "--check"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    if p.returncode != 0:
        sys.exit(p.stderr.strip() or f"objnerf batch --check exited {p.returncode}")
    return [json.loads(line) for line in p.stdout.splitlines() if line.strip()]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("manifest")
    ap.add_argument("--out", required=True)
    ap.add_argument("--objnerf", default="objnerf", help="the objnerf binary (default: on PATH)")
    ap.add_argument("--address", default=None, help="a Ray cluster (default: start a local Ray)")
    ap.add_argument("--cpus", type=float, default=1.0, help="CPUs a job without its own asks for")
    ap.add_argument("--memory-mb", type=int, default=2048, help="memory a job without its own asks for")
    ap.add_argument("--max-retries", type=int, default=3, help="Ray's retries of a task whose worker died")
    args = ap.parse_args()

    objnerf = os.path.abspath(args.objnerf) if os.sep in args.objnerf else args.objnerf
    manifest = os.path.abspath(args.manifest)
    out = os.path.abspath(args.out)
    jobs = check(objnerf, manifest)
    os.makedirs(out, exist_ok=True)

    ray.init(address=args.address, include_dashboard=False, logging_level="warning")
    task = ray.remote(run_job)
    refs = {}
    for job in jobs:
        res = job["resources"]
        cpus = res.get("cpus") or args.cpus
        memory_mb = res.get("memory_mb") or args.memory_mb
        ref = task.options(
            num_cpus=cpus,
            memory=memory_mb * 1024 * 1024,
            max_retries=args.max_retries,
            name=f"objnerf-batch-{job['id']}",
        ).remote(objnerf, manifest, out, job["id"])
        refs[ref] = job["id"]

    t0 = time.time()
    pending = list(refs)
    while pending:
        done, pending = ray.wait(pending, num_returns=1)
        job_id = refs[done[0]]
        try:
            r = ray.get(done[0])
            error = f": {r['error']}" if r.get("error") else ""
            print(f"{job_id}: {r['status']} in {r['seconds']:.0f} s, peak {r['peak_rss_mib']} MiB{error}",
                  file=sys.stderr, flush=True)
        except Exception as e:  # the task failed past its retries: the summary says "not run"
            print(f"{job_id}: no result: {e}", file=sys.stderr, flush=True)
    print(f"ray: {len(jobs)} jobs in {time.time() - t0:.0f} s", file=sys.stderr, flush=True)
    ray.shutdown()

    summary = subprocess.run([objnerf, "batch", manifest, "--out", out, "--summary"])
    sys.exit(summary.returncode)


if __name__ == "__main__":
    main()
