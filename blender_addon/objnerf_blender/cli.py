"""The `objnerf` binary, run as a subprocess: finding it, running short commands, and running
long ones (`render-edit`) in the background so Blender stays responsive.

The add-on is thin over the binary: the heavy work (segmentation, fields, rendering) stays in
Rust. Every failure here is an `ObjnerfError` that names the command and carries its stderr.
"""

import os
import shutil
import subprocess
import tempfile
import time

from .errors import ObjnerfError

# The binary's stderr is cut to this many characters in reports (the console gets all of it).
STDERR_TAIL = 1500


def find_binary(configured=""):
    """The objnerf executable: the preference when set, else `objnerf` on PATH."""
    if configured:
        path = os.path.abspath(os.path.expanduser(configured))
        if not os.path.isfile(path):
            raise ObjnerfError(f"objnerf binary not found at {path} (Preferences > Add-ons > objnerf)")
        if not os.access(path, os.X_OK):
            raise ObjnerfError(f"objnerf binary {path} is not executable")
        return path
    found = shutil.which("objnerf")
    if not found:
        raise ObjnerfError("objnerf binary not found on PATH; set its path in Preferences > Add-ons > objnerf")
    return found


def environment(models_dir=""):
    """The subprocess environment: the models directory becomes OBJNERF_HOME when given."""
    env = dict(os.environ)
    if models_dir:
        env["OBJNERF_HOME"] = os.path.abspath(os.path.expanduser(models_dir))
    return env


def tail(text, n=STDERR_TAIL):
    text = (text or "").strip()
    return text if len(text) <= n else "..." + text[-n:]


def run(binary, args, models_dir="", timeout=None):
    """Run `binary args...` to completion; returns stdout. A non-zero exit is an ObjnerfError
    with the command and the tail of its stderr."""
    cmd = [binary, *map(str, args)]
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, env=environment(models_dir), timeout=timeout)
    except FileNotFoundError as e:
        raise ObjnerfError(f"cannot run {binary}: not found") from e
    except OSError as e:
        raise ObjnerfError(f"cannot run {binary}: {e.strerror}") from e
    except subprocess.TimeoutExpired as e:
        raise ObjnerfError(f"'objnerf {args[0]}' did not finish within {timeout} s") from e
    if p.returncode != 0:
        print(p.stderr)
        raise ObjnerfError(f"'objnerf {' '.join(map(str, args))}' failed (exit {p.returncode}): {tail(p.stderr)}")
    return p.stdout


def has_command(binary, command):
    """Whether this objnerf knows `command` (its `--help` succeeds)."""
    try:
        return subprocess.run([binary, command, "--help"], capture_output=True, timeout=30).returncode == 0
    except (OSError, subprocess.TimeoutExpired):
        return False


def transforms_for_scene(scene, get_binary, models_dir=""):
    """A nerfstudio transforms.json for any scene objnerf reads, for importing its cameras.

    A transforms.json (or a folder holding one) is used as is; any other format (COLMAP, LLFF,
    RGB-D) goes through `objnerf export nerfstudio SCENE --out TMP` (issue 15), which owns the
    conversions. This is the only function that changes when that command lands.
    `get_binary()` is called only when the binary is needed. Returns (path, exported): an
    exported file's `applied_transform`, if any, is undone by the reader (the run's meshes are in
    the original format's frame).
    """
    if os.path.isfile(scene) and scene.endswith(".json"):
        return scene, False
    if os.path.isfile(os.path.join(scene, "transforms.json")):
        return os.path.join(scene, "transforms.json"), False
    if not os.path.exists(scene):
        raise ObjnerfError(f"scene {scene} does not exist")
    binary = get_binary()
    if not has_command(binary, "export"):
        raise ObjnerfError(
            f"scene {scene} is not a nerfstudio transforms.json; importing other formats needs "
            "'objnerf export nerfstudio', which this objnerf does not have yet")
    out = tempfile.mkdtemp(prefix="objnerf_export_")
    os.rmdir(out)  # the exporter creates its output folder
    run(binary, ["export", "nerfstudio", scene, "--out", out], models_dir)
    path = os.path.join(out, "transforms.json")
    if not os.path.isfile(path):
        raise ObjnerfError(f"'objnerf export nerfstudio {scene}' wrote no transforms.json in {out}")
    return path, True


class BackgroundJob:
    """A long objnerf command running in the background, polled by a modal operator's timer.

    Progress is counted from the files the command has written (`count_done()` is given by the
    caller), so it works whatever the binary prints. stdout/stderr go to files in the output
    folder, not pipes: a chatty child can never block on a full pipe while nobody reads.
    """

    def __init__(self, binary, args, log_dir, total, count_done, models_dir=""):
        self.cmd = [binary, *map(str, args)]
        self.total = max(1, int(total))
        self.count_done = count_done
        os.makedirs(log_dir, exist_ok=True)
        self.stderr_path = os.path.join(log_dir, "objnerf_stderr.log")
        self.stdout_path = os.path.join(log_dir, "objnerf_stdout.log")
        self._err = open(self.stderr_path, "w")
        self._out = open(self.stdout_path, "w")
        self.started = time.monotonic()
        try:
            self.proc = subprocess.Popen(self.cmd, stdout=self._out, stderr=self._err, env=environment(models_dir))
        except OSError as e:
            self._close()
            raise ObjnerfError(f"cannot run {binary}: {e.strerror}") from e
        self.cancelled = False

    def _close(self):
        for f in (self._err, self._out):
            if not f.closed:
                f.close()

    def progress(self):
        """Fraction done, 0..1, from the files written so far."""
        return min(1.0, self.count_done() / self.total)

    def poll(self):
        """None while running, else the exit code."""
        return self.proc.poll()

    def cancel(self):
        """Stop the command (SIGTERM, then SIGKILL after 5 s)."""
        self.cancelled = True
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self._close()

    def finish(self):
        """After the command exits: raise ObjnerfError with its stderr if it failed."""
        code = self.proc.wait()
        self._close()
        if self.cancelled:
            raise ObjnerfError("render cancelled")
        if code != 0:
            with open(self.stderr_path, errors="replace") as f:
                err = f.read()
            print(err)
            raise ObjnerfError(f"'objnerf {self.cmd[1]}' failed (exit {code}): {tail(err)}")

    def wait(self, poll_seconds=0.2, on_progress=None):
        """Block until done (for scripts and background mode, where no timer fires)."""
        while self.poll() is None:
            if on_progress:
                on_progress(self.progress())
            time.sleep(poll_seconds)
        self.finish()
