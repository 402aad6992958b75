"""Speed of many captures: one capture's stages, a batch's throughput, a dask cluster, start-up.

Tables printed (medians of repeated runs; the machine may be shared, so the load average is
printed with each table, and CPU seconds beside wall seconds):

1. ``stages``: ``inspect()`` of one 1280 x 800 example capture with diameters, per stage, with
   the segmentation model, OpenCV and BLAS on their default threads and on one thread each (as
   in a batch).
   Target: whole capture <= 1.0 s on 2 cores.
   ``parts``: CPU seconds per capture of each part of ``inspect()`` (the network, the rest of
   the mask, the geometry, the diameters, ...) on the paper slab's 4 captures, one thread, each
   part wrapped in a CPU-time counter (no profiler).
   ``network`` (only when asked for): the network's 36 runs of one capture, the model file's
   graph against the graph padded to whole channel blocks (docs/decisions/027), rounds
   interleaved in one process, and whether their outputs are the same to the bit.
2. ``startup``: ``rebar --help``, and ``rebar report --results`` of the 4-capture paper slab
   (PDF), wall time including the interpreter's start-up. Targets: 0.3 s and 3 s. Twice: as
   this environment runs them (where Python may not write bytecode, ``PYTHONDONTWRITEBYTECODE``
   or a read-only checkout, every run compiles rebarlib's modules; the table's title says which),
   and with every module's bytecode cached (in a temporary ``PYTHONPYCACHEPREFIX``, filled by
   one run first), as a user's second and later runs find them.
3. ``batch``: ``rebar inspect --jobs J`` over N copies of the paper slab's 4 captures (hard
   links): captures per minute and the peak memory of the whole process tree. Target:
   >= 100 captures/min for ``--jobs 2`` on 24 captures.
4. ``dask``: the same batch on a local dask.distributed cluster of 1, then 2 worker processes
   (one thread each): captures per minute and the scaling.
5. ``many`` (only when asked for, it is long): one ``rebar inspect --jobs 2`` over ``--count``
   copies (default 1000) made in a temporary folder and deleted afterwards: wall time, captures
   per minute, CPU seconds per capture, the peak memory of the process tree and of its largest
   process, and how many captures came out ``ok`` in ``summary.csv``. Target: 1000 captures in
   <= 10 min on 2 cores.

``--dump FILE`` writes the results of the five example captures (seed 0, timings left out) as
JSON; ``--check FILE`` runs them again and says whether every bar, spacing, count and measurement
is identical to the dump (a speed change must leave them so).

    python benchmarks/bench_batch.py                   # all tables, 24 captures, 3 repeats
    python benchmarks/bench_batch.py --only batch --n 200 --jobs 2
    python benchmarks/bench_batch.py --only many --count 1000   # the 1000-capture run (long)
    python benchmarks/bench_batch.py --dump before.json ; ...change... ; --check before.json
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples"
PAPER = EXAMPLES / "paper_slab"
REBAR = [sys.executable, "-m", "rebarlib"]


def load() -> str:
    avg = " / ".join(f"{x:.2f}" for x in os.getloadavg())
    return f"load average {avg} on {os.cpu_count()} cores"


def table(title: str, header: list, rows: list) -> None:
    print(f"\n## {title}  ({load()})\n")
    print("| " + " | ".join(header) + " |")
    print("|" + "|".join("---" for _ in header) + "|")
    for r in rows:
        print("| " + " | ".join(str(x) for x in r) + " |")
    sys.stdout.flush()


# ---------------------------------------------------------------------------------------------
# 1. one capture's stages


def _stage_run(threads: str, repeats: int) -> dict:
    code = f"""
import json, statistics, time, sys
import rebarlib._inspect as I
threads = {threads!r}
if threads != "default":  # as a batch's worker: the model, OpenCV and BLAS on these threads
    from rebarlib.batch import _configure_threads
    _configure_threads(int(threads))
from rebarlib import load_capture, load_design
d = load_design({str(PAPER / "design.toml")!r})
cap = load_capture({str(PAPER / "B_500")!r})
I.inspect(cap, d, rng=0)
walls, cpus, st = [], [], {{}}
for i in range({repeats}):
    t = time.perf_counter(); c = time.process_time(); r = I.inspect(cap, d, rng=0)
    walls.append(time.perf_counter() - t); cpus.append(time.process_time() - c)
    for k, v in r.timings_s.items():
        st.setdefault(k, []).append(v)
print(json.dumps({{"wall": statistics.median(walls), "cpu": statistics.median(cpus),
                  "stages": {{k: statistics.median(v) for k, v in st.items()}}}}))
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT)
    return json.loads(out.stdout.strip().splitlines()[-1])


def bench_stages(repeats: int) -> None:
    runs = {t: _stage_run(t, repeats) for t in ("default", "1")}
    stages = list(runs["default"]["stages"])
    rows = [[s] + [f"{runs[t]['stages'].get(s, float('nan')):.3f}" for t in runs] for s in stages]
    rows.append(["**whole capture, wall**"] + [f"**{runs[t]['wall']:.3f}**" for t in runs])
    rows.append(["whole capture, CPU"] + [f"{runs[t]['cpu']:.3f}" for t in runs])
    table(
        f"stages: inspect() of examples/paper_slab/B_500 with diameters, median of {repeats} (s)",
        ["stage", "threads: default", "threads: 1 (model, OpenCV, BLAS)"],
        rows,
    )


#: The parts of ``inspect()`` timed by the ``parts`` table: (label, module, attribute), each
#: wrapped in a CPU-time counter; nested parts are counted in their parent too.
PARTS = (
    ("network runs (onnxruntime)", "rebarlib.segmentation.model", "SegmentationModel._run"),
    ("tiled probability, network included", "rebarlib.segmentation.model", "SegmentationModel.predict_proba"),
    ("colour-depth registration (ECC)", "rebarlib.segmentation", "estimate_registration"),
    ("depth mask", "rebarlib.segmentation", "mask_from_depth"),
    ("depth over-reach", "rebarlib.segmentation", "depth_overreach_px"),
    ("fused and soft mask", "rebarlib.segmentation", "fuse_masks"),
    ("fused and soft mask", "rebarlib.segmentation", "soft_mask"),
    ("geometry (formwork, layers, bars, spacings, positions)", "rebarlib._refined", "inspect_refined"),
    ("diameters", "rebarlib.diameter", "measure_diameters"),
    ("uncertainty budget", "rebarlib.uncertainty", "apply_budget"),
)


def _parts_run(repeats: int) -> dict:
    code = f"""
import functools, importlib, json, time
from rebarlib.batch import _configure_threads
_configure_threads(1)  # as a batch's worker: the model, OpenCV and BLAS on one thread
import rebarlib._inspect as I
from rebarlib import load_capture, load_design
acc = {{}}
def wrap(label, mod, attr):
    owner = importlib.import_module(mod)
    *path, name = attr.split(".")
    for a in path:
        owner = getattr(owner, a)
    f = getattr(owner, name)
    @functools.wraps(f)
    def g(*a, **k):
        c = time.process_time()
        try:
            return f(*a, **k)
        finally:
            acc[label] = acc.get(label, 0.0) + time.process_time() - c
    setattr(owner, name, g)
for label, mod, attr in {PARTS!r}:
    wrap(label, mod, attr)
d = load_design({str(PAPER / "design.toml")!r})
names = ("A_400", "B_500", "C_600", "D_500")
c = time.process_time()
caps = [load_capture({str(PAPER)!r} + "/" + n) for n in names]
load = (time.process_time() - c) / len(caps)
I.inspect(caps[1], d, rng=0)  # warm-up: imports, the model's session
acc.clear()
whole = 0.0
for r in range({repeats}):
    for cap in caps:
        c = time.process_time(); I.inspect(cap, d, rng=0); whole += time.process_time() - c
n = {repeats} * len(caps)
out = {{k: v / n for k, v in acc.items()}}
out["loading a capture (load_capture)"] = load
out["whole inspect()"] = whole / n
print(json.dumps(out))
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT)
    return json.loads(out.stdout.strip().splitlines()[-1])


def bench_parts(repeats: int) -> None:
    """CPU seconds per capture of each part of ``inspect()``: the paper slab's 4 captures with
    diameters, the model, OpenCV and BLAS on one thread (as in a batch), no profiler (each part
    wrapped in a ``time.process_time`` counter)."""
    r = _parts_run(repeats)
    order = [p[0] for p in PARTS]
    labels = list(dict.fromkeys(order)) + ["loading a capture (load_capture)", "whole inspect()"]
    rows = [[k, f"{r[k]:.3f}"] for k in labels if k in r]
    table(
        f"parts: CPU s per capture of inspect() on the paper slab's 4 captures, 1 thread, mean of {repeats} rounds",
        ["part", "CPU s per capture"],
        rows,
    )


def bench_network(repeats: int) -> None:
    """CPU seconds of the network's 36 runs of one capture (B_500's 9 tiles, each with its three
    test-time flips), one thread, the model file's graph and the graph padded to whole channel
    blocks (``SegmentationModel.pad_layout``), in the same process, rounds interleaved; and
    whether their outputs are the same to the bit."""
    import numpy as np

    from rebarlib import load_capture
    from rebarlib.segmentation import SegmentationModel

    models = {}
    for padded in (False, True):
        SegmentationModel.pad_layout = padded
        models[padded] = SegmentationModel.default(threads=1)
    SegmentationModel.pad_layout = True
    m = models[False]
    img = np.asarray(load_capture(PAPER / "B_500").color)
    norm = m._normalised(img)
    (tw, th), (H, W) = m._inp["size"], img.shape[:2]
    inputs = []
    for y0 in sorted({*range(0, H - th + 1, th // 2), H - th}):
        for x0 in sorted({*range(0, W - tw + 1, tw // 2), W - tw}):
            t = m._laid_out(norm[y0 : y0 + th, x0 : x0 + tw])[0]
            inputs += [t] + [np.ascontiguousarray(np.flip(t, ax)) for ax in ((3,), (2,), (2, 3))]
    outs = {k: [mod._run(mod._session, x) for x in inputs] for k, mod in models.items()}
    same = all(a.tobytes() == b.tobytes() for a, b in zip(outs[False], outs[True]))
    cpu = {False: [], True: []}
    for r in range(repeats):
        for k in (False, True) if r % 2 == 0 else (True, False):
            mod = models[k]
            c = time.process_time()
            for x in inputs:
                mod._run(mod._session, x)
            cpu[k].append(time.process_time() - c)
    rows = [
        [name, f"{statistics.median(cpu[k]):.3f}", f"{min(cpu[k]):.3f}-{max(cpu[k]):.3f}"]
        for name, k in (("the model file's graph", False), ("padded to whole channel blocks", True))
    ]
    rows[1][0] += "" if models[True].layout_padded else " (not used on this CPU: the same graph)"
    table(
        f"network: {len(inputs)} runs of B_500's tiles and flips, 1 thread, CPU s, median of {repeats} "
        f"interleaved rounds; outputs the same to the bit: {same}",
        ["graph", "CPU s per capture's runs", "range"],
        rows,
    )


# ---------------------------------------------------------------------------------------------
# 2. start-up


def _timed(cmd, env=None) -> tuple:
    """Wall and CPU seconds (user + system, the command and its children) of one run."""
    import resource

    r0, t = resource.getrusage(resource.RUSAGE_CHILDREN), time.perf_counter()
    subprocess.run(cmd, capture_output=True, check=True, cwd=ROOT, env=env)
    wall, r1 = time.perf_counter() - t, resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)


def _median_of(cmds, env=None) -> tuple:
    runs = [_timed(c, env) for c in cmds]
    return statistics.median(w for w, _ in runs), statistics.median(c for _, c in runs)


def _rebarlib_bytecode_cached() -> bool:
    """Whether this interpreter finds rebarlib's modules compiled (``__pycache__``): Python
    compiles a module it finds without it on every import where it may not write the cache
    (``PYTHONDONTWRITEBYTECODE``, a read-only checkout)."""
    import importlib.util

    mods = sorted((ROOT / "rebarlib").rglob("*.py"))
    return all(Path(importlib.util.cache_from_source(str(m))).exists() for m in mods)


def _with_bytecode_cache(folder: Path) -> dict:
    """The environment of a run whose compiled modules are kept in ``folder`` (filled by the first
    run): how a user's second and later runs find them, without writing into the checkout."""
    env = dict(os.environ, PYTHONPYCACHEPREFIX=str(folder))
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    return env


def bench_startup(repeats: int) -> None:
    rebar = shutil.which("rebar", path=str(Path(sys.executable).parent)) or "rebar"
    with tempfile.TemporaryDirectory(prefix="bench_batch_") as tmp:
        res = Path(tmp) / "res"
        caps = [str(p) for p in sorted(PAPER.iterdir()) if p.is_dir()]
        subprocess.run(
            [
                *REBAR,
                "inspect",
                *caps,
                "--design",
                str(PAPER / "design.toml"),
                "--out",
                str(res),
                "--quiet",
                "--jobs",
                "2",
            ],
            check=True,
            cwd=ROOT,
            capture_output=True,
        )

        def report_cmds(tag):
            out = Path(tmp) / tag
            return [
                [rebar, "report", str(PAPER), "--results", str(res), "--out", str(out / f"r{i}.pdf")]
                for i in range(repeats)
            ]

        cached = _rebarlib_bytecode_cached()
        env = _with_bytecode_cache(Path(tmp) / "pyc")
        _timed(report_cmds("fill")[0], env)  # fills the cache
        rows = []
        for what, e in (("as this environment runs it", None), ("every module's bytecode cached", env)):
            help_ = _median_of([[rebar, "--help"]] * repeats, e)
            report = _median_of(report_cmds("env" if e is None else "pyc"), e)
            rows += [
                [f"rebar --help ({what})", f"{help_[0]:.3f}", f"{help_[1]:.3f}", "0.3"],
                [f"rebar report --results, 4 captures, PDF ({what})", f"{report[0]:.3f}", f"{report[1]:.3f}", "3.0"],
            ]
    table(
        f"startup: seconds with the interpreter's start-up, median of {repeats}; rebarlib's bytecode cached "
        f"in this environment: {'yes' if cached else 'no (every run compiles its modules)'}",
        ["command", "wall s", "CPU s", "target (wall)"],
        rows,
    )


# ---------------------------------------------------------------------------------------------
# 3. a batch with rebar inspect --jobs


def copies(folder: Path, n: int) -> list:
    """``n`` capture folders: the paper slab's captures, hard-linked (copied where links fail)."""
    src = sorted(p for p in PAPER.iterdir() if (p / "camera.json").is_file())
    out = []
    for i in range(n):
        dst = folder / f"{src[i % len(src)].name}_{i:04d}"
        try:
            shutil.copytree(src[i % len(src)], dst, copy_function=os.link)
        except OSError:
            shutil.copytree(src[i % len(src)], dst)
        out.append(dst)
    return out


class PeakMemory:
    """Peak resident memory of a process and its children (the whole tree, ``peak``; the largest
    single process, ``peak_one``), sampled every 0.2 s."""

    def __init__(self, pid: int):
        import psutil

        self.proc, self.peak, self.peak_one, self._stop = psutil.Process(pid), 0, 0, threading.Event()
        self._t = threading.Thread(target=self._run, daemon=True)
        self._t.start()

    def _run(self):
        import psutil

        while not self._stop.is_set():
            try:
                procs = [self.proc] + self.proc.children(recursive=True)
                rss = 0
                for p in procs:
                    try:
                        one = p.memory_info().rss
                    except psutil.Error:
                        continue
                    rss += one
                    self.peak_one = max(self.peak_one, one)
                self.peak = max(self.peak, rss)
            except psutil.Error:
                pass
            self._stop.wait(0.2)

    def stop(self) -> float:
        self._stop.set()
        self._t.join()
        return self.peak / 2**20


def run_batch(caps: list, out: Path, *extra, memory: list | None = None) -> tuple:
    """``rebar inspect`` over ``caps``: (wall s, peak MiB of the process tree, exit status, CPU s
    of the command and its worker processes). ``memory``: a list the peak MiB of the largest
    single process is appended to."""
    import resource

    cpu0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    cmd = [
        *REBAR,
        "inspect",
        *map(str, caps),
        "--design",
        str(PAPER / "design.toml"),
        "--out",
        str(out),
        "--quiet",
        *extra,
    ]
    p = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    mem = PeakMemory(p.pid)
    _, err = p.communicate()
    wall = time.perf_counter() - t
    peak = mem.stop()
    if memory is not None:
        memory.append(mem.peak_one / 2**20)
    cpu1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (cpu1.ru_utime - cpu0.ru_utime) + (cpu1.ru_stime - cpu0.ru_stime)
    if p.returncode != 0:
        print(err, file=sys.stderr)
    return wall, peak, p.returncode, cpu


def bench_batch(n: int, jobs_list: list, repeats: int) -> None:
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench_batch_") as tmp:
        caps = copies(Path(tmp) / "caps", n)
        for jobs in jobs_list:
            walls, peaks, cpus = [], [], []
            for r in range(repeats):
                wall, peak, rc, cpu = run_batch(caps, Path(tmp) / f"out_{jobs}_{r}", "--jobs", str(jobs))
                walls.append(wall)
                peaks.append(peak)
                cpus.append(cpu)
            w = statistics.median(walls)
            rows.append(
                [
                    jobs,
                    n,
                    f"{w:.1f}",
                    f"{60 * n / w:.1f}",
                    f"{statistics.median(cpus) / n:.2f}",
                    f"{max(peaks):.0f}",
                    rc,
                ]
            )
    table(
        f"batch: rebar inspect --jobs J over {n} copies of the paper slab's captures "
        f"(diameters on), median of {repeats}",
        ["jobs", "captures", "wall s", "captures/min", "CPU s per capture (all processes)", "peak MiB (tree)", "exit"],
        rows,
    )


# ---------------------------------------------------------------------------------------------
# 4. dask


def bench_dask(n: int, repeats: int) -> None:
    from distributed import LocalCluster

    rows, rate1 = [], None
    with tempfile.TemporaryDirectory(prefix="bench_batch_") as tmp:
        caps = copies(Path(tmp) / "caps", n)
        for workers in (1, 2):
            with LocalCluster(
                n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None, host="127.0.0.1"
            ) as cluster:
                address = cluster.scheduler_address
                # a first small batch lets every worker import the stages before the clock starts
                run_batch(caps[: 2 * workers], Path(tmp) / f"warm_{workers}", "--dask", address)
                walls = [
                    run_batch(caps, Path(tmp) / f"out_{workers}_{r}", "--dask", address)[0] for r in range(repeats)
                ]
            w = statistics.median(walls)
            rate = 60 * n / w
            rate1 = rate1 or rate
            rows.append([workers, n, f"{w:.1f}", f"{rate:.1f}", f"{rate / rate1:.2f}"])
    table(
        f"dask: rebar inspect --dask on a local cluster (1 thread per worker), {n} captures, median of {repeats}",
        ["workers", "captures", "wall s", "captures/min", "scaling"],
        rows,
    )


# ---------------------------------------------------------------------------------------------
# 5. many captures: the 1000-capture run


def bench_many(count: int, jobs: int = 2) -> int:
    """One ``rebar inspect --jobs`` over ``count`` copies of the paper slab's captures (hard links
    in a temporary folder, deleted afterwards, results included). Returns the command's exit
    status."""
    import csv

    load_before = " / ".join(f"{x:.2f}" for x in os.getloadavg())
    with tempfile.TemporaryDirectory(prefix="bench_many_") as tmp:
        t = time.perf_counter()
        caps = copies(Path(tmp) / "caps", count)
        made = time.perf_counter() - t
        print(f"{count} capture folders linked in {made:.1f} s; running rebar inspect --jobs {jobs} ...", flush=True)
        out, one = Path(tmp) / "out", []
        wall, peak, rc, cpu = run_batch(caps, out, "--jobs", str(jobs), memory=one)
        with open(out / "summary.csv", newline="", encoding="utf-8") as f:
            statuses = [row["status"] for row in csv.DictReader(f)]
    rows = [
        ["captures", count],
        ["jobs", jobs],
        ["wall s", f"{wall:.1f}"],
        ["captures/min", f"{60 * count / wall:.1f}"],
        ["CPU s per capture (all processes)", f"{cpu / count:.2f}"],
        ["peak MiB, process tree", f"{peak:.0f}"],
        ["peak MiB, largest process", f"{one[0]:.0f}"],
        ["summary.csv rows ok / failed", f"{statuses.count('ok')} / {statuses.count('failed')}"],
        ["exit status", rc],
        ["load average before", load_before],
        [
            f"target: {count} captures in <= {count * 0.6:.0f} s (1000 in 10 min)",
            "met" if wall <= 0.6 * count else "not met",
        ],
    ]
    table(
        f"many: rebar inspect --jobs {jobs} over {count} copies of the paper slab's captures, one run",
        ["what", "measured"],
        rows,
    )
    return rc


# ---------------------------------------------------------------------------------------------
# accuracy unchanged


def dump_results() -> dict:
    from rebarlib import inspect, load_capture, load_design

    out = {}
    for slab in ("paper_slab", "site_slab"):
        design = load_design(EXAMPLES / slab / "design.toml")
        for cap in sorted(p for p in (EXAMPLES / slab).iterdir() if (p / "camera.json").is_file()):
            r = inspect(load_capture(cap), design, rng=0).to_dict()
            r.pop("timings_s", None)
            out[f"{slab}/{cap.name}"] = r
    return json.loads(json.dumps(out, sort_keys=True, default=str))


def _differences(a, b, path="") -> list:
    if isinstance(a, dict) and isinstance(b, dict):
        return [d for k in sorted(set(a) | set(b)) for d in _differences(a.get(k), b.get(k), f"{path}.{k}")]
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in _differences(x, y, f"{path}[{i}]")]
    return [] if a == b else [f"{path}: {a!r} -> {b!r}"]


def check(path: Path) -> int:
    before = json.loads(path.read_text(encoding="utf-8"))
    now = dump_results()
    bad = 0
    for key in sorted(set(before) | set(now)):
        diff = _differences(before.get(key), now.get(key))
        bad += bool(diff)
        said = "identical" if not diff else f"{len(diff)} differences, e.g. " + "; ".join(diff[:5])
        print(f"{key}: {said}")
    return 1 if bad else 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument(
        "--only", choices=("stages", "parts", "network", "startup", "batch", "dask", "many"), action="append"
    )
    ap.add_argument("--n", type=int, default=24, help="captures in the batch and dask tables (default 24)")
    ap.add_argument("--jobs", type=int, action="append", help="--jobs values of the batch table (default 1 and 2)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--count", type=int, default=1000, help="captures of the many table (default 1000)")
    ap.add_argument("--big", type=int, metavar="N", help="the same as --only many --count N")
    ap.add_argument("--dump", type=Path, metavar="FILE")
    ap.add_argument("--check", type=Path, metavar="FILE")
    a = ap.parse_args(argv)
    if a.dump:
        a.dump.write_text(json.dumps(dump_results(), indent=1, sort_keys=True), encoding="utf-8")
        print(f"results of the five examples written to {a.dump}")
        return 0
    if a.check:
        return check(a.check)
    if a.big:
        return bench_many(a.big)
    only = set(a.only or ("stages", "parts", "startup", "batch", "dask"))
    if "stages" in only:
        bench_stages(max(a.repeats, 5))
    if "parts" in only:
        bench_parts(a.repeats)
    if "network" in only:
        bench_network(max(a.repeats, 5))
    if "startup" in only:
        bench_startup(max(a.repeats, 5))
    if "batch" in only:
        bench_batch(a.n, a.jobs or [1, 2], a.repeats)
    if "dask" in only:
        bench_dask(a.n, a.repeats)
    if "many" in only:
        return bench_many(a.count, (a.jobs or [2])[0])
    return 0


if __name__ == "__main__":
    sys.exit(main())
