"""optimize(): the CLI's recovery, its callback, its interruption and its resumption."""

import json
from pathlib import Path

import numpy as np
import pytest

import translucent as tl
from conftest import run_cli

# A short run of the defaults: the learned fit, then the tracer's refinement, the intervals and
# the checks, on 4 views of 16 × 16 pixels.
SHORT = dict(iterations=6, spp=4, uncertainty_views=4, uncertainty_spp=4, final_spp=4, seed=0)


def without_timings(x):
    """result.json without what depends on the clock or the output folder's name."""
    if isinstance(x, dict):
        return {
            k: without_timings(v)
            for k, v in x.items()
            if "second" not in k and k not in ("out", "dataset", "elapsed")
        }
    if isinstance(x, list):
        return [without_timings(v) for v in x]
    return x


def test_optimize_equals_the_cli(tmp_path, dataset, cli):
    res = tl.optimize(dataset, tmp_path / "py", threads=2, verbose=False, **SHORT)
    run_cli(
        cli, "--threads", "2", "optimize", "--dataset", dataset.path, "--out", tmp_path / "cli",
        "--iterations", "6", "--spp", "4", "--uncertainty-views", "4", "--uncertainty-spp", "4",
        "--final-spp", "4", "--seed", "0",
    )
    ours = json.loads((tmp_path / "py" / "result.json").read_text())
    theirs = json.loads((tmp_path / "cli" / "result.json").read_text())
    assert without_timings(ours) == without_timings(theirs)
    assert res.to_dict() == ours
    assert res.status in ("ok", "failed") and res.iterations == 6
    assert set(res.estimate) >= {"sigma_t", "albedo"} and len(res.estimate["sigma_t"]) == 3
    assert res.interval95 is not None and res.determined is not None
    assert "status" in str(res)
    csv = (tmp_path / "py" / "iterations.csv").read_text().splitlines()
    assert len(csv) == 7
    # The run's Mitsuba 3 scene reads back as the dataset's rig made of the estimate.
    back = tl.mitsuba.load_scene(tmp_path / "py" / "mitsuba" / "scene.xml")
    assert len(back) == 4 and back.images == [None] * 4
    assert np.allclose(back.to_world, dataset.to_world, atol=1e-5)
    assert np.allclose(back.light_positions, dataset.light_positions, atol=1e-5)
    assert back.truth.sigma_t == pytest.approx(res.estimate["sigma_t"], rel=1e-5)
    assert back.truth.albedo == pytest.approx(res.estimate["albedo"], rel=1e-5)


def test_the_callback_sees_every_iteration_and_stops_the_run(tmp_path, dataset):
    seen = []

    def stop_after_two(iteration, params, loss):
        seen.append((iteration, params["sigma_t"], loss))
        return iteration < 2

    res = tl.optimize(dataset, tmp_path / "o", callback=stop_after_two, threads=2, verbose=False, **SHORT)
    assert [s[0] for s in seen] == [0, 1, 2]
    assert all(len(s[1]) == 3 and s[2] > 0 for s in seen)
    assert res.status == "interrupted" and res.iterations == 3
    assert res.raw["complete"] is False
    assert (tmp_path / "o" / "checkpoint.json").is_file()
    # Resumed, it runs to the end from the checkpoint.
    more = []
    done = tl.optimize(
        dataset, tmp_path / "o", callback=lambda i, p, l: more.append(i), resume=True,
        threads=2, verbose=False, **SHORT,
    )
    assert more == [3, 4, 5]
    assert done.status in ("ok", "failed") and done.iterations == 6


def test_an_exception_in_the_callback_is_raised_after_a_clean_stop(tmp_path, dataset):
    def broken(iteration, params, loss):
        raise RuntimeError("from the callback")

    with pytest.raises(RuntimeError, match="from the callback"):
        tl.optimize(dataset, tmp_path / "o", callback=broken, threads=2, verbose=False, **SHORT)
    assert json.loads((tmp_path / "o" / "result.json").read_text())["status"] == "interrupted"


def test_a_dataset_made_in_memory_is_saved_with_the_run(tmp_path, scene_file):
    ds = tl.Dataset.from_scene(scene_file)
    ds = ds.with_images(tl.render(ds, spp=4, seed=0, threads=2).images)
    res = tl.optimize(ds, tmp_path / "o", threads=2, verbose=False, model="volpath", **SHORT)
    assert (tmp_path / "o" / "dataset" / "dataset.json").is_file()
    assert res.raw["method"]
    with pytest.raises(FileExistsError):
        tl.optimize(ds, tmp_path / "o", threads=2, verbose=False, model="volpath", **SHORT)


def test_ctrl_c_stops_a_run_cleanly_and_raises_keyboard_interrupt(tmp_path, dataset):
    import os
    import signal
    import threading

    started = threading.Event()

    def mark(iteration, params, loss):
        started.set()

    timer = threading.Timer(0.0, lambda: (started.wait(30), os.kill(os.getpid(), signal.SIGINT)))
    timer.start()
    long = {**SHORT, "iterations": 2000}
    with pytest.raises(KeyboardInterrupt):
        tl.optimize(dataset, tmp_path / "o", callback=mark, threads=2, verbose=False, **long)
    timer.join()
    result = json.loads((tmp_path / "o" / "result.json").read_text())
    assert result["status"] == "interrupted" and 0 < result["iterations"] < 2000
    assert (tmp_path / "o" / "checkpoint.json").is_file()
