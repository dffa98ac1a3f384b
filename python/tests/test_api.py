"""The Python API: every entry, its errors, and agreement with the command line."""

import json
from pathlib import Path

import numpy as np
import pytest

import translucent as tl
from conftest import run_cli


def test_medium_fields_defaults_and_replace():
    m = tl.Medium(sigma_t=30, albedo=(0.9, 0.8, 0.7))
    assert m.sigma_t == (30, 30, 30)
    assert m.albedo == pytest.approx((0.9, 0.8, 0.7))
    assert (m.g, m.eta, m.roughness) == (0, 1, 0)
    r = m.replace(g=0.6, eta=1.4, roughness=0.3)
    assert (r.g, r.eta, r.roughness) == pytest.approx((0.6, 1.4, 0.3))
    assert r.sigma_t == m.sigma_t
    assert tl.Medium(**m.to_dict()) == m


def test_a_g_per_channel_reads_back_and_is_refused_where_mitsuba_has_one():
    m = tl.Medium(sigma_t=30, albedo=0.9, g=(0.3, 0.5, 0.7))
    assert m.g == pytest.approx((0.3, 0.5, 0.7))
    assert tl.Medium(**m.to_dict()) == m
    assert m.replace(g=0.4).g == pytest.approx(0.4)
    assert "g=(0.3, 0.5, 0.7)" in repr(m)
    with pytest.raises(ValueError, match=r"g\[1\] = 1"):
        tl.Medium(sigma_t=30, albedo=0.9, g=(0.3, 1.0, 0.7))
    from translucent import mitsuba

    with pytest.raises(ValueError, match="one g"):
        mitsuba.medium_dict(m)
    assert "g-rgb" in tl.default_options()["free"][1]


@pytest.mark.parametrize(
    "kwargs, field",
    [
        (dict(sigma_t=-1, albedo=0.5), "sigma_t[0] = -1"),
        (dict(sigma_t=(1, 2, float("nan")), albedo=0.5), "sigma_t[2]"),
        (dict(sigma_t=10, albedo=1.0), "albedo[0] = 1"),
        (dict(sigma_t=10, albedo=0.5, g=1.0), "g = 1"),
        (dict(sigma_t=10, albedo=0.5, eta=0.9), "eta = 0.9"),
        (dict(sigma_t=10, albedo=0.5, roughness=0.2), "roughness = 0.2"),
    ],
)
def test_medium_errors_name_the_field_and_the_fix(kwargs, field):
    with pytest.raises(ValueError, match="fix") as e:
        tl.Medium(**kwargs)
    assert field in str(e.value)


def test_measured_medium_in_real_units():
    mm = tl.Medium.measured("marble", "mm")
    cm = tl.Medium.measured("marble", "cm")
    # Jensen et al. 2001's marble: σ_t ≈ 2.2–3.0 per mm, ten times that per cm.
    assert 2.0 < mm.sigma_t[0] < 3.1
    assert cm.sigma_t[0] == pytest.approx(10 * mm.sigma_t[0], rel=1e-5)
    with pytest.raises(ValueError, match="unit"):
        tl.Medium.measured("marble", "inch")
    with pytest.raises(ValueError):
        tl.Medium.measured("no such medium")


def test_mitsuba_dicts_follow_the_boundary():
    m = tl.Medium(sigma_t=(10, 20, 40), albedo=0.9, g=0.6)
    assert tl.mitsuba.bsdf_dict(m) == {"type": "null"}
    assert tl.mitsuba.bsdf_dict(m.replace(eta=1.5))["type"] == "dielectric"
    rough = tl.mitsuba.bsdf_dict(m.replace(eta=1.4, roughness=0.3))
    assert rough["type"] == "roughdielectric" and rough["distribution"] == "ggx"
    assert rough["alpha"] == pytest.approx(0.3) and rough["int_ior"] == pytest.approx(1.4)
    med = tl.mitsuba.medium_dict(m)
    # σ_t = value × scale, values in [0, 1].
    assert med["scale"] == 40
    assert np.allclose(np.array(med["sigma_t"]["value"]) * med["scale"], [10, 20, 40])
    assert med["phase"] == {"type": "hg", "g": pytest.approx(0.6)}
    shape = tl.mitsuba.shape_dict(m, "object.ply")
    assert shape["type"] == "ply" and shape["interior"] == med
    with pytest.raises(ValueError):
        tl.mitsuba.shape_dict(m, "object.stl")


def test_dataset_views_as_arrays(scene_file):
    ds = tl.Dataset.from_scene(scene_file)
    assert len(ds) == 4
    assert ds.to_world.shape == (4, 4, 4) and ds.to_world.dtype == np.float32
    # Rotation columns are orthonormal; the last row is (0, 0, 0, 1).
    r = ds.to_world[:, :3, :3]
    assert np.allclose(np.einsum("nij,nik->njk", r, r), np.eye(3), atol=1e-5)
    assert np.allclose(ds.to_world[:, 3], [0, 0, 0, 1])
    k = ds.intrinsics
    assert k.shape == (4, 4)
    # fov 40° on 16 pixels: f = 8 / tan(20°), principal point at the centre.
    assert np.allclose(k[:, 0], 8 / np.tan(np.radians(20)), rtol=1e-5)
    assert np.allclose(k[:, 2:], 8)
    assert np.array_equal(ds.resolution, [[16, 16]] * 4)
    assert np.allclose(ds.light_positions, [1.0, 1.5, 0.5])
    assert np.allclose(ds.light_intensities, 4.0)
    v, f = ds.mesh
    assert v.shape[1] == 3 and f.shape[1] == 3 and f.max() < len(v)
    assert ds.images == [None] * 4
    assert ds.truth.sigma_t == (40, 50, 60)
    assert ds.object == {"eta": 1.0, "roughness": 0.0, "g": 0.0}
    assert ds.length_unit is None


def test_a_scene_in_millimetres_names_a_measured_medium(tmp_path, scene_file):
    """A scene file's `length_unit` and `measured` medium: the marble of the CLI's `dataset
    --measured marble --units mm`, and the unit saved with the dataset."""
    text = scene_file.read_text()
    text = 'length_unit = "mm"\n' + text.replace(
        "sigma_t = [40.0, 50.0, 60.0]\nalbedo = [0.95, 0.90, 0.85]", 'measured = "marble"'
    )
    (tmp_path / "mm.toml").write_text(text)
    ds = tl.Dataset.from_scene(tmp_path / "mm.toml")
    assert ds.length_unit == "mm"
    # Jensen et al.'s marble at g 0: σ_t = σ_s' + σ_a in 1/mm.
    assert ds.truth.sigma_t == pytest.approx((2.19 + 0.0021, 2.62 + 0.0041, 3.00 + 0.0071), rel=1e-5)
    r = tl.render(ds, spp=2, seed=0, threads=2)
    saved = ds.with_images(r.images).save(tmp_path / "mm-dataset")
    assert tl.Dataset.load(tmp_path / "mm-dataset").length_unit == "mm"
    with pytest.raises(ValueError, match="length_unit"):
        (tmp_path / "bad.toml").write_text(text.replace('length_unit = "mm"\n', ""))
        tl.Dataset.from_scene(tmp_path / "bad.toml")
    assert saved.length_unit == "mm"


def test_render_equals_the_cli_bit_for_bit(tmp_path, scene_file, cli):
    r = tl.render(scene_file, spp=8, seed=3, threads=2)
    run_cli(cli, "--threads", "2", "render", scene_file, "--spp", "8", "--seed", "3", "--out", tmp_path / "cli")
    for i, img in enumerate(r.images):
        assert img.shape == (16, 16, 3) and img.dtype == np.float32
        assert np.array_equal(img, tl.read_image(tmp_path / "cli" / f"view_{i:03d}.exr"))
    # A Dataset renders the same as its scene file, and the seed matters.
    same = tl.render(tl.Dataset.from_scene(scene_file), spp=8, seed=3, threads=2)
    assert all(np.array_equal(a, b) for a, b in zip(r.images, same.images))
    other = tl.render(scene_file, spp=8, seed=4, threads=2)
    assert not np.array_equal(r.images[0], other.images[0])


def test_render_derivatives_and_models(scene_file):
    medium = tl.Medium(sigma_t=30, albedo=0.8, g=0.3)
    r = tl.render(scene_file, medium, spp=4, seed=0, derivatives=True, threads=2)
    for parts in (r.d_sigma_t, r.d_albedo, r.d_g):
        assert len(parts) == 4 and parts[0].shape == (16, 16, 3)
    # Brighter with more albedo, everywhere it is lit on average.
    assert r.d_albedo[0].sum() > 0
    plain = tl.render(scene_file, medium, spp=4, seed=0, threads=2)
    assert plain.d_sigma_t is None
    assert np.array_equal(plain.images[0], r.images[0])
    for model in ("learned", "dipole"):
        m = tl.render(scene_file, spp=4, seed=0, model=model, threads=2)
        assert m.model == model
        assert all(np.isfinite(i).all() and i.mean() > 0 for i in m.images)
    with pytest.raises(ValueError, match="model"):
        tl.render(scene_file, model="mitsuba")
    with pytest.raises(ValueError, match="spp"):
        tl.render(scene_file, spp=0)


def test_dataset_from_arrays_saves_and_reads_back(tmp_path, scene_file):
    src = tl.Dataset.from_scene(scene_file)
    images = tl.render(src, spp=4, seed=0, threads=2).images
    v, f = src.mesh
    ds = tl.make_dataset(
        v.astype(np.float64),
        f.astype(np.int64),
        to_world=src.to_world,
        resolution=(16, 16),
        intrinsics=src.intrinsics,
        light_positions=src.light_positions,
        light_intensities=(4.0, 4.0, 4.0),
        images=images,
        eta=1.33,
        roughness=0.1,
        g=0.5,
        length_unit="mm",
    )
    assert ds.path is None and ds.object["g"] == pytest.approx(0.5)
    saved = ds.save(tmp_path / "arrays")
    assert saved.path == tmp_path / "arrays" and (tmp_path / "arrays" / "mesh.ply").is_file()
    assert np.allclose(saved.to_world, src.to_world, atol=1e-6)
    assert np.allclose(saved.intrinsics, src.intrinsics, rtol=1e-5)
    for a, b in zip(saved.images, images):
        assert np.array_equal(a, b)
    assert saved.object == pytest.approx({"eta": 1.33, "roughness": 0.1, "g": 0.5})
    assert json.loads((tmp_path / "arrays" / "dataset.json").read_text())["length_unit"] == "mm"
    with pytest.raises(FileExistsError, match="overwrite=True"):
        ds.save(tmp_path / "arrays")
    ds.save(tmp_path / "arrays", overwrite=True)


def test_arrays_of_the_wrong_shape_or_dtype(scene_file):
    src = tl.Dataset.from_scene(scene_file)
    good = np.zeros((16, 16, 3), np.float32)
    with pytest.raises(ValueError, match=r"images\[1\].*float32.*float64"):
        src.with_images([good, good.astype(np.float64), good, good])
    with pytest.raises(ValueError, match=r"images\[0\].*shape"):
        src.with_images([np.zeros((16, 16, 4), np.float32)] + [good] * 3)
    with pytest.raises(ValueError, match=r"images\[0\] is 8 × 16"):
        src.with_images([np.zeros((16, 8, 3), np.float32)] + [good] * 3)
    with pytest.raises(ValueError, match="one per view"):
        src.with_images([good])
    bad = good.copy()
    bad[3, 4, 1] = np.nan
    with pytest.raises(ValueError, match="not finite|finite"):
        src.with_images([bad] + [good] * 3)
    v, f = src.mesh
    common = dict(resolution=(16, 16), fov_x=40, light_positions=(0, 0, 3), light_intensities=(1, 1, 1))
    with pytest.raises(ValueError, match=r"to_world: expected an array of shape \(N, 4, 4\)"):
        tl.make_dataset(v, f, to_world=np.eye(4), **common)
    with pytest.raises(ValueError, match="vertices"):
        tl.make_dataset(v[:, :2], f, to_world=src.to_world, **common)
    with pytest.raises(ValueError, match="faces: expected integers"):
        tl.make_dataset(v, f.astype(np.float32), to_world=src.to_world, **common)
    with pytest.raises(ValueError, match="faces: index"):
        tl.make_dataset(v, f + len(v), to_world=src.to_world, **common)
    with pytest.raises(ValueError, match="fov_x"):
        tl.make_dataset(v, f, to_world=src.to_world, **{**common, "fov_x": None})
    with pytest.raises(ValueError, match="image"):
        tl.write_image("x.exr", [[1.0, 2.0]])


def test_images_and_errors_of_files(tmp_path):
    img = np.random.default_rng(0).random((5, 7, 3), dtype=np.float32)
    tl.write_image(tmp_path / "a.exr", img)
    assert np.array_equal(tl.read_image(tmp_path / "a.exr"), img)
    tl.write_image(tmp_path / "a.png", img)
    with pytest.raises(FileExistsError, match="overwrite=True"):
        tl.write_image(tmp_path / "a.exr", img)
    with pytest.raises(OSError, match="missing"):
        tl.Dataset.load(tmp_path / "missing")
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match="dataset.json"):
        tl.Dataset.load(tmp_path / "empty")
    with pytest.raises(ValueError, match="image"):
        tl.write_image(tmp_path / "a.tiff", img)


def test_default_options_are_the_products():
    d = tl.default_options()
    assert d["iterations"][0] == 300 and d["spp"][0] == 32
    assert d["model"][0] == "learned"
    assert d["init_sigma_t"][0] == (50, 50, 50) and d["init_albedo"][0] == (0.5, 0.5, 0.5)
    assert all(isinstance(help, str) and help for _, help in d.values())


def test_options_are_checked(dataset, tmp_path):
    with pytest.raises(TypeError, match="iteratons.*iterations"):
        tl.optimize(dataset, tmp_path / "o", iteratons=3)
    with pytest.raises(ValueError, match="spp = 0"):
        tl.optimize(dataset, tmp_path / "o", spp=0)
    with pytest.raises(ValueError, match="free"):
        tl.optimize(dataset, tmp_path / "o", free=["eta"])
    with pytest.raises(ValueError, match="model"):
        tl.optimize(dataset, tmp_path / "o", model="mitsuba")


def test_a_render_releases_the_gil(scene_file):
    import threading

    ticks = []
    done = threading.Event()

    def count():
        while not done.is_set():
            ticks.append(1)
            done.wait(0.001)

    t = threading.Thread(target=count)
    t.start()
    before = len(ticks)
    tl.render(scene_file, spp=256, seed=0, threads=1)
    during = len(ticks) - before
    done.set()
    t.join()
    # The counting thread ran while Rust rendered (it could not have without the GIL).
    assert during > 10
