"""Shared fixtures: a small scene (a sphere seen from 4 directions at 16 × 16 pixels), its dataset
rendered by the volumetric path tracer, and the command-line binary the results are compared
with."""

import os
import shutil
import subprocess
from pathlib import Path

import pytest

import translucent as tl

SCENE = """\
shape = {{ name = "sphere", scale = 0.5 }}

[medium]
sigma_t = [40.0, 50.0, 60.0]
albedo = [0.95, 0.90, 0.85]
g = {g}

[rig]
views = 4
radius = 2.0
fov = 40.0
width = 16
height = 16
light = "fixed"
light_position = [1.0, 1.5, 0.5]
intensity = 4.0

[render]
spp = 16
seed = 0
"""

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture
def scene_file(tmp_path: Path) -> Path:
    p = tmp_path / "scene.toml"
    p.write_text(SCENE.format(g=0.0))
    return p


@pytest.fixture
def dataset(tmp_path: Path, scene_file: Path) -> tl.Dataset:
    """The scene's dataset, rendered by the tracer at 16 spp (seed 0, 2 threads) and saved."""
    ds = tl.Dataset.from_scene(scene_file)
    r = tl.render(ds, spp=16, seed=0, threads=2)
    return ds.with_images(r.images).save(tmp_path / "dataset")


@pytest.fixture
def cli() -> Path:
    """The `translucent` binary: $TRANSLUCENT_BIN, else the workspace's test or release build."""
    env = os.environ.get("TRANSLUCENT_BIN")
    candidates = [Path(env)] if env else [REPO / "target/debug/translucent", REPO / "target/release/translucent"]
    for c in candidates:
        if c.is_file() and os.access(c, os.X_OK):
            return c
    if env:
        pytest.fail(f"TRANSLUCENT_BIN={env} is not an executable")
    pytest.skip("no translucent binary built (cargo build --release, or set TRANSLUCENT_BIN)")


def run_cli(cli: Path, *args: str) -> None:
    subprocess.run([str(cli), "--quiet", *map(str, args)], check=True, capture_output=True)
