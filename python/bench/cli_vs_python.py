"""What a Python call costs against the same work by the `translucent` binary, side by side in
one run: `render` of a scene and a recovery of 30 iterations with the defaults, each timed as
wall-clock seconds of the whole call (the binary's process included), alternating the two.

    python python/bench/cli_vs_python.py --bin target/release/translucent [--reps 5] [--threads 2]

Prints a Markdown table (median seconds, Python ÷ CLI) for BENCHMARKS.md.
"""

import argparse
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import translucent as tl

SCENE = """\
shape = { name = "sphere", scale = 0.5 }
[medium]
sigma_t = [40.0, 50.0, 60.0]
albedo = [0.95, 0.90, 0.85]
[rig]
views = 8
radius = 2.0
fov = 40.0
width = 64
height = 64
light = "fixed"
light_position = [1.0, 1.5, 0.5]
intensity = 4.0
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", required=True, help="the translucent binary")
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    t = str(a.threads)
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        (d / "scene.toml").write_text(SCENE)
        ds = tl.Dataset.from_scene(d / "scene.toml")
        ds = ds.with_images(tl.render(ds, spp=64, seed=a.seed, threads=a.threads).images).save(d / "ds")
        cases = {
            "render: 8 views of 64², 64 spp, volpath": (
                [a.bin, "--quiet", "--threads", t, "render", d / "scene.toml", "--spp", "64",
                 "--seed", str(a.seed), "--out", d / "r", "--overwrite"],
                lambda: tl.render(d / "scene.toml", spp=64, seed=a.seed, threads=a.threads),
            ),
            "optimize: 30 iterations, the defaults": (
                [a.bin, "--quiet", "--threads", t, "optimize", "--dataset", d / "ds", "--out",
                 d / "o-cli", "--iterations", "30", "--seed", str(a.seed), "--overwrite"],
                lambda: tl.optimize(ds, d / "o-py", iterations=30, seed=a.seed, threads=a.threads,
                                    verbose=False, overwrite=True),
            ),
        }
        print("| work | CLI (s, median) | Python (s, median) | Python ÷ CLI |")
        print("|---|---|---|---|")
        for name, (cmd, call) in cases.items():
            cli, py = [], []
            for _ in range(a.reps):
                t0 = time.perf_counter()
                subprocess.run([str(c) for c in cmd], check=True, capture_output=True)
                cli.append(time.perf_counter() - t0)
                t0 = time.perf_counter()
                call()
                py.append(time.perf_counter() - t0)
            c, p = statistics.median(cli), statistics.median(py)
            print(f"| {name} | {c:.3f} | {p:.3f} | {p / c:.3f} |")


if __name__ == "__main__":
    main()
