"""Captures in: a COLMAP model with photos and masks, and a NeRF transforms.json, as the CLI's
`translucent import` reads them."""

import json

import numpy as np
import pytest

import translucent as tl
from conftest import run_cli


def test_a_colmap_capture_imports_as_the_cli_imports_it(tmp_path, cli):
    cap = tmp_path / "cap"
    run_cli(
        cli, "dataset", "--shape", "sphere", "--views", "2", "--res", "16", "--spp", "16",
        "--light", "attached", "--units", "cm", "--as-capture", "--out", cap,
    )
    flash = (-0.8, -0.8, 0.0)
    ours = tl.import_colmap(
        cap / "sparse", cap / "images", cap / "object.ply", flash=flash, masks=cap / "masks",
        intensity=10, units="cm",
    )
    run_cli(
        cli, "import", "colmap", cap / "sparse", "--images", cap / "images", "--masks", cap / "masks",
        "--mesh", cap / "object.ply", "--flash=-0.8,-0.8,0", "--intensity", "10", "--units", "cm",
        "--out", tmp_path / "imported",
    )
    theirs = tl.Dataset.load(tmp_path / "imported")
    assert ours.path is None and len(ours) == len(theirs) == 2
    for name in ("to_world", "intrinsics", "resolution", "light_positions", "light_intensities"):
        assert np.allclose(getattr(ours, name), getattr(theirs, name), atol=1e-6), name
    for a, b in zip(ours.images, theirs.images):
        assert np.array_equal(a, b)
    # Saved, it is the CLI's dataset.
    saved = ours.save(tmp_path / "saved")
    doc = json.loads((tmp_path / "saved" / "dataset.json").read_text())
    assert doc["length_unit"] == "cm"
    assert all(np.array_equal(a, b) for a, b in zip(saved.images, theirs.images))
    with pytest.raises(ValueError, match="flash"):
        tl.import_colmap(cap / "sparse", cap / "images", cap / "object.ply")
    with pytest.raises(ValueError, match="transfer"):
        tl.import_colmap(cap / "sparse", cap / "images", cap / "object.ply", flash=flash, transfer="gamma")
    with pytest.raises(ValueError, match="no COLMAP model here.*fix"):
        tl.import_colmap(tmp_path / "none", cap / "images", cap / "object.ply", flash=flash)


def test_a_transforms_json_imports_as_the_dataset_it_came_from(tmp_path, dataset):
    # The dataset's cameras as OpenGL camera-to-world matrices (x right, y up, looking along
    # −z): Mitsuba's x points left and z forward.
    frames = []
    for i, (m, light) in enumerate(zip(dataset.to_world, dataset.light_positions)):
        gl = m.astype(float).copy()
        gl[:3, 0] *= -1
        gl[:3, 2] *= -1
        frames.append({
            "file_path": f"view_{i:03d}",
            "transform_matrix": gl.tolist(),
            "light_position": light.tolist(),
        })
    fov = 2 * np.arctan(8 / dataset.intrinsics[0, 0])
    doc = {"camera_angle_x": float(fov), "frames": frames}
    (dataset.path / "transforms.json").write_text(json.dumps(doc))
    ours = tl.import_nerf(
        dataset.path / "transforms.json", _mesh(tmp_path, dataset), intensity=4, transfer="linear"
    )
    assert len(ours) == 4
    assert np.allclose(ours.to_world, dataset.to_world, atol=1e-5)
    assert np.allclose(ours.light_positions, dataset.light_positions)
    assert np.allclose(ours.intrinsics, dataset.intrinsics, rtol=1e-4)
    for a, b in zip(ours.images, dataset.images):
        assert np.array_equal(a, b)
    for fr in doc["frames"]:
        del fr["light_position"]
    (dataset.path / "transforms.json").write_text(json.dumps(doc))
    with pytest.raises(ValueError, match="no frame states a light"):
        tl.import_nerf(dataset.path / "transforms.json", _mesh(tmp_path, dataset))


def _mesh(tmp_path, dataset):
    """The dataset's mesh as a PLY file (written by saving a one-view dataset of it)."""
    path = tmp_path / "mesh-only" / "mesh.ply"
    if not path.exists():
        v, f = dataset.mesh
        tl.make_dataset(
            v, f, to_world=dataset.to_world[:1], resolution=(16, 16), fov_x=40,
            light_positions=(0, 0, 3), light_intensities=(1, 1, 1),
            images=[np.zeros((16, 16, 3), np.float32)],
        ).save(tmp_path / "mesh-only")
    return path
