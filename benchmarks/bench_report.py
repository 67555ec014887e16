"""Report benchmark: `laminid report` of one S1.1 result, as whole commands and in-process.

A result of S1.1 (12x12 by default) is made first with `laminid identify ... -o` in a temporary
folder (or SOURCE is used: a result file or a batch summary). Then the whole commands
``laminid report SOURCE -o r.pdf --force`` and ``-o r.png --force``, with
``laminid identify S1.1.yaml --json --no-output`` as the yardstick, run alternately (median of
CLI_REPEAT each, wall and CPU time of the process: on a loaded machine the CPU time is the
steadier); report / identify is the figure to compare between machines. In-process, the pages'
building (report_pages: reading the result, the figures, the initial model's modes for the MAC)
and their writing as a PDF (write_pages: each page laid out once and drawn once), CPU time,
median of REPEAT, fresh pages each time.

Run: .venv/bin/python benchmarks/bench_report.py [--mesh 12x12] [--cli 5] [--repeat 3] [SOURCE]
"""

import _timing  # noqa: F401  first: sets single-threaded BLAS

import argparse  # noqa: E402
import os  # noqa: E402
import resource  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SPEC = ROOT / "specimens/example1/S1.1.yaml"
REPEAT = 3
CLI_REPEAT = 5


def cli(args, tmp) -> None:
    p = subprocess.run([sys.executable, "-m", "laminid_cli", *map(str, args)], env=dict(os.environ),
                       cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if p.returncode not in (0, 1):            # identify: 1 = not converged, still a figure
        sys.exit(f"laminid {' '.join(map(str, args))} failed ({p.returncode}): {p.stderr}")


def whole_commands(source: Path, tmp: Path, repeat: int) -> None:
    # as installed, from bytecode (see bench_identify.cli_ratio)
    subprocess.run([sys.executable, "-m", "compileall", "-q", str(ROOT / "laminid_cli")],
                   check=True, stdout=subprocess.DEVNULL)
    cmds = {"report -o r.pdf": ["report", source, "-o", tmp / "r.pdf", "--force"],
            "report -o r.png": ["report", source, "-o", tmp / "r.png", "--force"],
            "identify --json --no-output": ["identify", SPEC, "--json", "--no-output"]}
    wall = {k: [] for k in cmds}
    cpu = {k: [] for k in cmds}
    for _ in range(repeat):
        for k, c in cmds.items():
            r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
            t = time.perf_counter()
            cli(c, tmp)
            wall[k].append(time.perf_counter() - t)
            r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu[k].append(r1.ru_utime + r1.ru_stime - r0.ru_utime - r0.ru_stime)
    ref = "identify --json --no-output"
    for k in cmds:
        w, c = statistics.median(wall[k]), statistics.median(cpu[k])
        ratio = ("" if k == ref else f"  = {w / statistics.median(wall[ref]):.2f} / "
                 f"{c / statistics.median(cpu[ref]):.2f} x identify (wall / CPU)")
        print(f"CLI {k:<28} wall {w:5.2f} s  CPU {c:5.2f} s{ratio}", flush=True)
    print(f"(median of {repeat}, run alternately; pages: "
          f"{len(list(tmp.glob('r-*.png'))) or 1})")


def in_process(source: Path, tmp: Path, repeat: int) -> None:
    from laminid_cli.report import _initial_shapes, report_pages, write_pages

    report_pages(source)                       # imports, the font cache: not timed
    builds, writes = [], []
    for _ in range(repeat):
        _initial_shapes.cache_clear()          # the MAC's initial model, solved once a process
        t = time.process_time()
        pages = report_pages(source)
        builds.append(time.process_time() - t)
        t = time.process_time()
        write_pages(pages, tmp / "in.pdf")
        writes.append(time.process_time() - t)
    print(f"in-process (CPU): {len(pages)} pages ({', '.join(p.name for p in pages)}) built in "
          f"{statistics.median(builds):.2f} s, written as a PDF in "
          f"{statistics.median(writes):.2f} s; median of {repeat}")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("source", nargs="?", help="a result file or a batch summary (default: "
                    "S1.1 identified first)")
    ap.add_argument("--mesh", default="12x12", help="mesh of the S1.1 result made first")
    ap.add_argument("--cli", type=int, default=CLI_REPEAT, help="runs of each whole command")
    ap.add_argument("--repeat", type=int, default=REPEAT, help="in-process builds and writes")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        if a.source:
            source = Path(a.source).resolve()
        else:
            source = tmp / "S1.1.result.h5"
            cli(["identify", SPEC, "--mesh", a.mesh, "-o", source], tmp)
        if a.cli:
            whole_commands(source, tmp, a.cli)
        if a.repeat:
            in_process(source, tmp, a.repeat)
