"""Throughput and memory of the per-shape stages as the data grows (``docs/results/scaling.md``).

For each stage (``prepare``, ``render``, ``pseudo-label``), executor (``local`` with 1 worker =
in process, ``local`` with 2 worker processes, ``ray`` with 2 CPUs) and data size (objects made
by ``kinmo synth``, first N of one generated set; or the real shared objects), one
measurement runs in its own subprocess (``run``), which reports:

- wall seconds of the stage and shapes per second (Ray's start-up timed separately: Ray is
  started before the stage, as a cluster would already be running);
- CPU seconds of the process and all its descendants (sampled from ``/proc``: user + system);
- peak resident memory (``VmHWM``) of the driver and of the largest worker process (local pool
  workers, or Ray worker processes), sampled every 0.2 s from ``/proc``;
- the bytes written and the 1-minute load average before and after: the machine is shared,
  so the load of the other users is part of every figure.

``limits`` measures, in the same run, the machine's physical limits the stages could hit:
memory bandwidth (numpy copy of 256 MB) against the batched candidate motions of
refinement (:func:`kinmo.geometry.apply_motions`, bytes written per second), and the disk
write rate (256 MB written and fsync'ed) against the stages' output rates. ``report`` turns
the JSON lines into a Markdown table and a PNG plot.

Usage::

    python bench/bench_scaling.py all --sizes 100,300,1000 --out /work/exp/scale/scaling
    python bench/bench_scaling.py real --out /work/exp/scale/scaling
    python bench/bench_scaling.py limits --out /work/exp/scale/scaling
    python bench/bench_scaling.py report --out /work/exp/scale/scaling --png docs/results/scaling.png
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
STAGES = ("prepare", "render", "pseudo-label")
EXECUTORS = (("local", 1), ("local", 2), ("ray", 2))
TICK = os.sysconf("SC_CLK_TCK")


# ------------------------------------------------------------------ sampling of /proc


def _descendants(root: int) -> list[int]:
    children: dict[int, list[int]] = {}
    for d in os.listdir("/proc"):
        if not d.isdigit():
            continue
        try:
            with open(f"/proc/{d}/stat") as f:
                ppid = int(f.read().rsplit(")", 1)[1].split()[1])
        except (OSError, IndexError, ValueError):
            continue
        children.setdefault(ppid, []).append(int(d))
    out, todo = [], [root]
    while todo:
        p = todo.pop()
        for c in children.get(p, []):
            out.append(c)
            todo.append(c)
    return out


def _proc(pid: int) -> tuple[str, float, float] | None:
    """(kind, VmHWM MB, CPU seconds) of a process, None if gone."""
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            cmd = f.read().replace(b"\0", b" ").decode(errors="replace")
        with open(f"/proc/{pid}/status") as f:
            hwm = next((float(l.split()[1]) / 1024 for l in f if l.startswith("VmHWM")), 0.0)
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        cpu = (int(fields[11]) + int(fields[12])) / TICK
    except (OSError, IndexError, ValueError):
        return None
    system = ("raylet", "gcs_server", "dashboard", "log_monitor", "monitor.py", "runtime_env",
              "resource_tracker", "ray_client_server")
    kind = "system" if any(k in cmd for k in system) else "worker"  # pool or Ray workers
    return kind, hwm, cpu


class Sampler:
    """Peak memory and CPU time of this process's descendants, sampled in a thread."""

    def __init__(self, interval: float = 0.2) -> None:
        self.interval = interval
        self.seen: dict[int, tuple[str, float, float]] = {}
        self._stop = threading.Event()
        self._t = threading.Thread(target=self._loop, daemon=True)

    def _loop(self) -> None:
        while not self._stop.is_set():
            self.sample()
            self._stop.wait(self.interval)

    def sample(self) -> None:
        for pid in _descendants(os.getpid()):
            p = _proc(pid)
            if p is not None:
                old = self.seen.get(pid)
                self.seen[pid] = (p[0], max(p[1], old[1] if old else 0.0), p[2])

    def __enter__(self) -> Sampler:
        self._t.start()
        return self

    def __exit__(self, *exc) -> None:
        self.sample()
        self._stop.set()
        self._t.join()


# ------------------------------------------------------------------ one measurement


def untrained_models(folder: Path) -> tuple[Path, Path]:
    """An untrained motion GNN (quick preset) and axis network, saved as runs (the cost of
    pseudo-labelling does not depend on the weights)."""
    import torch

    from kinmo.features import SemanticVocab
    from kinmo.models.motion_gnn import MotionGNN
    from kinmo.refine.axis_net import AxisSelectionNet
    from kinmo.refine.train import preset_config, save_axis_model
    from kinmo.train.config import preset
    from kinmo.train.gnn import save_checkpoint

    gnn, axis = folder / "gnn", folder / "axis"
    if not (gnn / "model.pt").is_file():
        torch.manual_seed(0)
        cfg = preset("quick")
        save_checkpoint(gnn / "model.pt", MotionGNN(cfg.model), cfg, SemanticVocab(), None, 0)
        save_axis_model(axis / "model.pt", AxisSelectionNet(preset_config("quick").net))
    return gnn, axis


def run_one(stage: str, executor: str, workers: int, data: Path, out: Path, models: Path,
            frames: int) -> dict:
    """Run one stage on ``data`` into a fresh ``out``; the measurement as a dict."""
    import resource

    shutil.rmtree(out, ignore_errors=True)
    n = sum(1 for p in data.iterdir() if p.is_dir())
    load0 = os.getloadavg()[0]
    ray_start = 0.0
    if executor == "ray":
        import ray

        t = time.perf_counter()
        ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False,
                 configure_logging=False, object_store_memory=200 * 2**20)
        ray_start = time.perf_counter() - t
    with Sampler() as s:
        c0 = time.process_time()
        t0 = time.perf_counter()
        if stage == "prepare":
            from kinmo.prepare import prepare_dataset

            res = prepare_dataset(data, out, workers=workers, force=True, progress=False,
                                  executor=executor)
            failed = res.count("failed")
        elif stage == "render":
            from kinmo.render.dataset import RenderConfig, render_dataset

            res = render_dataset(data, out, frames, RenderConfig(width=128, height=96, seed=0),
                                 workers=workers, force=True, progress=False, executor=executor)
            failed = len(res.failed_objects)
        else:
            from kinmo.pseudo_label import PseudoLabelConfig, pseudo_label_dataset

            gnn, axis = untrained_models(models)
            res = pseudo_label_dataset(data, gnn, axis, out, PseudoLabelConfig(threshold=0.0),
                                       workers=workers, force=True, progress=False,
                                       executor=executor)
            failed = res.count("failed")
        wall = time.perf_counter() - t0
        cpu_self = time.process_time() - c0
    if executor == "ray":
        import ray

        ray.shutdown()
    workers_seen = [v for v in s.seen.values() if v[0] == "worker"]
    out_bytes = sum(p.stat().st_size for p in out.rglob("*") if p.is_file() and not p.is_symlink())
    shutil.rmtree(out, ignore_errors=True)  # the shared disk is small
    return {
        "stage": stage, "executor": executor, "workers": workers, "n": n,
        "frames": frames if stage == "render" else None,
        "wall_s": round(wall, 3), "shapes_per_s": round(n / wall, 3),
        "cpu_s": round(cpu_self + sum(v[2] for v in s.seen.values()), 2),
        "ray_start_s": round(ray_start, 2),
        "driver_peak_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
        "worker_peak_mb": round(max((v[1] for v in workers_seen), default=0.0), 1),
        "n_worker_procs": len(workers_seen),
        "system_peak_mb": round(sum(v[1] for v in s.seen.values() if v[0] == "system"), 1),
        "out_mb": round(out_bytes / 2**20, 2), "failed": failed,
        "load_before": round(load0, 2), "load_after": round(os.getloadavg()[0], 2),
        "cpus": os.cpu_count(),
    }


# ------------------------------------------------------------------ data and driver


def synth(folder: Path, n: int, partnet: bool) -> Path:
    """``kinmo synth`` of ``n`` objects into ``folder`` (reused when complete); its seconds
    are written to ``folder/.seconds``."""
    if (folder / ".complete").is_file():
        return folder
    shutil.rmtree(folder, ignore_errors=True)
    t = time.perf_counter()
    cmd = [sys.executable, "-m", "kinmo", "synth", str(folder), "--n", str(n), "--seed", "0", "--quiet"]
    subprocess.run(cmd + (["--partnet"] if partnet else []), check=True)
    (folder / ".seconds").write_text(f"{time.perf_counter() - t:.2f}\n")
    (folder / ".complete").write_text("")
    return folder


def subset(src: Path, n: int, dst: Path) -> Path:
    """A folder of links to the first ``n`` object folders of ``src`` (sorted)."""
    shutil.rmtree(dst, ignore_errors=True)
    dst.mkdir(parents=True)
    for p in sorted(q for q in src.iterdir() if q.is_dir())[:n]:
        (dst / p.name).symlink_to(p.resolve(), target_is_directory=True)
    return dst


def measure(stage: str, executor: str, workers: int, data: Path, work: Path, log: Path,
            frames: int, label: str) -> None:
    cmd = [sys.executable, __file__, "run", "--stage", stage, "--executor", executor,
           "--workers", str(workers), "--data", str(data), "--work", str(work),
           "--frames", str(frames)]
    t = time.perf_counter()
    res = subprocess.run(cmd, capture_output=True, text=True, env={**os.environ, "OMP_NUM_THREADS": "1"})
    if res.returncode != 0:
        print(f"FAILED {stage} {executor} {workers} {data}: {res.stderr[-2000:]}", file=sys.stderr)
        return
    row = json.loads(res.stdout.strip().splitlines()[-1])
    row["data"] = label
    with open(log, "a") as f:
        f.write(json.dumps(row) + "\n")
    print(f"{label:>10} {stage:>12} {executor}x{workers}: n={row['n']} {row['shapes_per_s']:.2f}/s "
          f"worker peak {row['worker_peak_mb']} MB driver {row['driver_peak_mb']} MB load "
          f"{row['load_before']}->{row['load_after']} ({time.perf_counter() - t:.0f} s)", flush=True)


def done(log: Path) -> set[tuple]:
    if not log.is_file():
        return set()
    return {(r["data"], r["stage"], r["executor"], r["workers"])
            for r in map(json.loads, log.read_text().splitlines())}


def cmd_all(a: argparse.Namespace) -> None:
    out = Path(a.out)
    log = out / "scaling.jsonl"
    sizes = [int(s) for s in a.sizes.split(",")]
    stages = a.stages.split(",")
    big = max(sizes)
    mob = synth(out / "synth" / f"mobility-{big}", big, False) if {"prepare", "render"} & set(stages) else None
    pn = synth(out / "synth" / f"partnet-{big}", big, True) if "pseudo-label" in stages else None
    have = done(log)
    for n in sizes:
        for stage in stages:
            src = pn if stage == "pseudo-label" else mob
            data = subset(src, n, out / "subsets" / f"{stage}-{n}")
            for ex, w in _executors(a):
                if (f"synth-{n}", stage, ex, w) in have:
                    continue
                measure(stage, ex, w, data, out / "work", log, a.frames, f"synth-{n}")


def _executors(a: argparse.Namespace) -> list[tuple[str, int]]:
    if not a.executors:
        return list(EXECUTORS)
    return [(e.split(":")[0], int(e.split(":")[1])) for e in a.executors.split(",")]


def cmd_real(a: argparse.Namespace) -> None:
    out = Path(a.out)
    log = out / "scaling.jsonl"
    data = Path(a.data)
    have = done(log)
    for stage in a.stages.split(","):
        src = data / ("partnet" if stage == "pseudo-label" else "partnet-mobility")
        label = f"real-{sum(1 for p in src.iterdir() if p.is_dir())}"
        for ex, w in _executors(a):
            if (label, stage, ex, w) not in have:
                measure(stage, ex, w, src, out / "work", log, a.frames, label)


def cmd_run(a: argparse.Namespace) -> None:
    row = run_one(a.stage, a.executor, a.workers, Path(a.data), Path(a.work) / "out",
                  Path(a.work) / "models", a.frames)
    print(json.dumps(row))


# ------------------------------------------------------------------ physical limits


def cmd_limits(a: argparse.Namespace) -> None:
    import numpy as np

    from kinmo.geometry import apply_motions

    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    res: dict = {"load_before": os.getloadavg()[0]}
    src = np.ones(32 * 2**20, np.float64)  # 256 MB
    dst = np.empty_like(src)
    ts = []
    for _ in range(5):
        t = time.perf_counter()
        np.copyto(dst, src)
        ts.append(time.perf_counter() - t)
    # a copy reads and writes every byte
    res["memcpy_gb_s"] = round(2 * src.nbytes / float(np.median(ts)) / 1e9, 2)
    rng = np.random.default_rng(0)
    c, n = 256, 4096  # candidate motions x points, as in refinement (bench_refine sizes)
    pts = rng.normal(size=(n, 3))
    o, d = rng.normal(size=(c, 3)), rng.normal(size=(c, 3))
    ang, tr = rng.uniform(-1, 1, c), rng.uniform(-1, 1, c)
    apply_motions(pts, o, d, ang, tr)
    ts = []
    for _ in range(20):
        t = time.perf_counter()
        apply_motions(pts, o, d, ang, tr)
        ts.append(time.perf_counter() - t)
    res["apply_motions_gb_s"] = round(c * n * 3 * 8 / float(np.median(ts)) / 1e9, 2)
    res["apply_motions_ms"] = round(1e3 * float(np.median(ts)), 3)
    buf = os.urandom(2**20)
    path = out / "disk_probe.bin"
    t = time.perf_counter()
    with open(path, "wb") as f:
        for _ in range(256):
            f.write(buf)
        f.flush()
        os.fsync(f.fileno())
    res["disk_write_mb_s"] = round(256 / (time.perf_counter() - t), 1)
    path.unlink()
    res["load_after"] = os.getloadavg()[0]
    (out / "limits.json").write_text(json.dumps(res, indent=1) + "\n")
    print(json.dumps(res))


# ------------------------------------------------------------------ report


def cmd_report(a: argparse.Namespace) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(a.out)
    rows = [json.loads(l) for l in (out / "scaling.jsonl").read_text().splitlines()]
    for r in rows:
        r["cpu_ms_per_shape"] = round(1e3 * r["cpu_s"] / r["n"], 1)
    cols = ["data", "stage", "executor", "workers", "n", "wall_s", "shapes_per_s", "cpu_s",
            "cpu_ms_per_shape", "ray_start_s", "worker_peak_mb", "driver_peak_mb",
            "system_peak_mb", "out_mb", "failed", "load_before", "load_after"]
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for r in sorted(rows, key=lambda r: (r["stage"], r["data"].startswith("real"), r["n"],
                                         r["executor"], r["workers"])):
        lines.append("| " + " | ".join(str(r[c]) for c in cols) + " |")
    (out / "scaling.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    fig, axes = plt.subplots(2, 3, figsize=(13, 7), sharex=True)
    for j, stage in enumerate(STAGES):
        for ex, w in EXECUTORS:
            pts = sorted((r["n"], r["wall_s"], r["cpu_s"],
                          r["driver_peak_mb"] if r["workers"] == 1 else r["worker_peak_mb"])
                         for r in rows if r["stage"] == stage and r["executor"] == ex
                         and r["workers"] == w and r["data"].startswith("synth"))
            if not pts:
                continue
            n, wall, cpu, mem = zip(*pts)
            label = f"{ex} x{w}" + (" (in process)" if ex == "local" and w == 1 else "")
            line = axes[0, j].plot(n, wall, "o-", label=f"{label} wall")[0]
            axes[0, j].plot(n, cpu, "s--", color=line.get_color(), alpha=0.6, label=f"{label} CPU")
            axes[1, j].plot(n, mem, "o-", label=label)
        axes[0, j].set_title(stage)
        axes[0, j].set_xscale("log")
        axes[0, j].set_yscale("log")
        axes[0, j].grid(True, which="both", alpha=0.3)
        axes[1, j].grid(True, alpha=0.3)
        axes[1, j].set_xlabel("generated objects")
        axes[1, j].set_ylim(bottom=0)
    axes[0, 0].set_ylabel("seconds (log): wall -, CPU --")
    axes[1, 0].set_ylabel("peak RSS per worker (MB; x1: the process)")
    axes[0, 0].legend(fontsize=7)
    fig.suptitle("kinmo per-shape stages on a shared 2-core machine (load average in the table)")
    fig.tight_layout()
    fig.savefig(a.png, dpi=110)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    r.add_argument("--stage", choices=STAGES, required=True)
    r.add_argument("--executor", default="local")
    r.add_argument("--workers", type=int, default=1)
    r.add_argument("--data", required=True)
    r.add_argument("--work", required=True)
    r.add_argument("--frames", type=int, default=2)
    for name in ("all", "real", "limits", "report"):
        s = sub.add_parser(name)
        s.add_argument("--out", default="/tmp/kinmo-scaling")
        s.add_argument("--sizes", default="100,300,1000")
        s.add_argument("--stages", default=",".join(STAGES))
        s.add_argument("--frames", type=int, default=2)
        s.add_argument("--executors", default="", help="e.g. local:1,local:2,ray:2 (default: all)")
        s.add_argument("--data", default=str(REPO.parent / "shared" / "data"))
        s.add_argument("--png", default=str(REPO / "docs" / "results" / "scaling.png"))
    a = p.parse_args()
    {"run": cmd_run, "all": cmd_all, "real": cmd_real, "limits": cmd_limits,
     "report": cmd_report}[a.cmd](a)


if __name__ == "__main__":
    main()
