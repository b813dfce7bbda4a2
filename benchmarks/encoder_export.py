"""Time per sample of the encoder-level packages (``export-c --from-encoders``), in C.

Run from the repository root: ``python -m benchmarks.encoder_export``; it prints the table
and writes it to ``reports/bench/encoder_export.md``.

Each package is exported, built with CMake (Release, the package's own flags) and its
``timing`` program run for a million samples on one core (``taskset``-like affinity of this
process, inherited by the program): the counts of the software in the loop's run played back
in a cycle, ``<prefix>_init`` untimed between cycles, the first sample of each move (the
global start) reported apart. The median and 99.99th percentile are over the other samples;
the maximum includes whatever the OS did meanwhile (no core isolation, no SCHED_FIFO here).
The operation count is the header's static bound; ns per operation relates the two.
"""

from __future__ import annotations

import json
import subprocess
import tempfile
from pathlib import Path

from benchmarks.peers.timing import pin_to_one_core
from benchmarks.tables import one_core_run, publish
from cdpr_sym.export import export_encoder_c

#: (robot, design, target median us, target 99.99th percentile us) of the issue; None: none.
CASES = (("aras3", "ida-winch", 5.0, 20.0), ("aras3", "smooth-lp", 5.0, 20.0),
         ("spatial6", "ida-winch", None, None), ("spatial6", "smooth-lp", None, None))
SAMPLES = 1_000_000
OUT = Path(__file__).resolve().parents[1] / "reports" / "bench" / "encoder_export.md"


def timed(robot: str, design: str, folder: Path) -> dict:
    """The timing program's JSON for one package."""
    result = export_encoder_c(robot, design, folder / "package")
    build = folder / "build"
    subprocess.run(["cmake", "-S", str(result.out_dir), "-B", str(build),
                    "-DCMAKE_BUILD_TYPE=Release"], check=True, capture_output=True)
    subprocess.run(["cmake", "--build", str(build), "-j", "2"], check=True,
                   capture_output=True)
    sil = json.loads(subprocess.run([str(build / "sil")], capture_output=True, text=True,
                                    check=False).stdout)
    done = subprocess.run([str(build / "timing"), str(SAMPLES)], check=True,
                          capture_output=True, text=True)
    return {**json.loads(done.stdout), "sil_agrees": sil["agrees"]}


def _verdict(value: float, target: float | None) -> str:
    return "" if target is None else (" (met)" if value <= target else " (**missed**)")


def main() -> None:
    pin_to_one_core(1)
    rows = []
    with tempfile.TemporaryDirectory() as scratch:
        for robot, design, median_target, tail_target in CASES:
            folder = Path(scratch) / f"{robot}_{design}"
            folder.mkdir()
            measured = timed(robot, design, folder)
            rows.append(
                f"| {robot} | `{design}` | {measured['operations']:,} | "
                f"{measured['median_us']:.2f}{_verdict(measured['median_us'], median_target)} | "
                f"{measured['p999_us']:.2f} | "
                f"{measured['p9999_us']:.2f}{_verdict(measured['p9999_us'], tail_target)} | "
                f"{measured['max_us']:.1f} | {measured['over_10x_median']:,} | "
                f"{measured['first_sample_max_us']:.1f} | "
                f"{1e3 * measured['median_us'] / measured['operations']:.2f} | "
                f"{'yes' if measured['sil_agrees'] else 'NO'} |")
    lines = ["# Encoder-level packages: time per sample in C", "",
             one_core_run("python -m benchmarks.encoder_export") +
             f" {SAMPLES:,} samples per package (the software in the loop's counts in a "
             "cycle); no core isolation or real-time priority, so the maximum holds the OS's "
             "interruptions. Targets (issue): aras3 median <= 5 us, 99.99th percentile <= 20 "
             "us; ipanema8 <= 20 / 60 us, not measured: its default as-built run loses the "
             "pose at t = 0 and the export refuses it (docs/encoder_export.md, Limits).", "",
             "| robot | design | operations per sample | median us | 99.9th pct us | "
             "99.99th pct us | max us | samples over 10x median | first sample max us | "
             "ns per operation | software in the loop agrees |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---|", *rows, "",
             "The 99.99th percentile is the operating system's, not the code's: the kernel "
             "here ticks at 250 Hz (CONFIG_HZ=250) on a 2-core virtual machine, so a "
             "timer interrupt lands in about one timed window in (4 ms / window) and costs "
             "tens of microseconds; with windows of 0.5-5 us that is 1e-4 to 1e-3 of the "
             "samples, at or above the 99.99th percentile's 1e-4 (the column of samples over "
             "ten times the median counts them). The operation count bounds the code's own "
             "path; on a real-time target (isolated core with nohz_full, SCHED_FIFO, locked "
             "memory) the tail is that path plus the platform's interrupt latency."]
    publish(OUT, lines)


if __name__ == "__main__":
    main()
