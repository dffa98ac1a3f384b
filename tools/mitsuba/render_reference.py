#!/usr/bin/env python3
"""Re-render a reference folder (scene.json + mesh + view_XXX.exr, the format of
../shared/reference-renders) with Mitsuba 3's own `volpath`, for timings and seed-to-seed spreads
on this machine.

    python3 -m venv .mi && .mi/bin/pip install mitsuba   # Mitsuba 3.9.1 wheels; llvm needs libLLVM
    .mi/bin/python tools/mitsuba/render_reference.py ../shared/reference-renders/mitsuba-sphere-rgb-64 \
        --out out/mi-seed1 --seed 1 [--spp 1024] [--variant llvm_ad_rgb] [--threads 2]

Writes OUT/view_XXX.exr (linear float32 RGB, as the reference), copies scene.json and the mesh so
OUT is itself a reference folder (`translucent compare OUT REF`, `translucent validate-mitsuba
OUT`), and prints per-view seconds and mean RGB. The scene is built from scene.json exactly as its
own words say (null boundary, homogeneous medium encoded as rgb·scale, point light, perspective
camera with fov along x, box filter, independent sampler, volpath max_depth/rr_depth). Not used by
the tests or CI: Mitsuba is a reference, not a dependency.
"""
import argparse
import json
import shutil
import sys
import time
from pathlib import Path


def sensor_dict(fov, fov_axis, to_world, width, height, spp, clip=None, offset=(0.0, 0.0)):
    """Mitsuba's description of one of our cameras: a perspective sensor (`fov` degrees along
    `fov_axis`), `to_world` an `mi.ScalarTransform4f`, box filter, linear RGB `hdrfilm`,
    independent sampler at `spp`; `clip` = (near, far) when the folder gives them; `offset` the
    principal-point offsets (fractions of the film) of a calibrated camera."""
    d = {
        "type": "perspective",
        "fov": fov,
        "fov_axis": fov_axis,
        "to_world": to_world,
        "film": {
            "type": "hdrfilm",
            "width": width,
            "height": height,
            "rfilter": {"type": "box"},
            "pixel_format": "rgb",
        },
        "sampler": {"type": "independent", "sample_count": spp},
    }
    if clip is not None:
        d["near_clip"], d["far_clip"] = clip
    if tuple(offset) != (0.0, 0.0):
        d["principal_point_offset_x"], d["principal_point_offset_y"] = offset
    return d


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("ref", type=Path, help="reference folder (scene.json + mesh)")
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--spp", type=int, default=None, help="default: the reference's own")
    ap.add_argument("--spp-per-pass", type=int, default=None, help="default: the reference's own (memory)")
    ap.add_argument("--max-depth", type=int, default=None, help="default: the reference's own")
    ap.add_argument("--rr-depth", type=int, default=None, help="default: the reference's own")
    ap.add_argument("--res", type=int, default=None, help="square resolution instead of the reference's")
    ap.add_argument("--variant", default="llvm_ad_rgb")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--overwrite", action="store_true")
    a = ap.parse_args()

    import drjit as dr
    import mitsuba as mi

    mi.set_variant(a.variant)
    if a.variant.startswith("llvm"):
        dr.set_thread_count(a.threads)
    desc = json.loads((a.ref / "scene.json").read_text())
    spp = a.spp or desc["render"]["spp"]
    per_pass = min(spp, a.spp_per_pass or desc["render"].get("spp_per_pass", spp))
    if spp % per_pass:
        sys.exit(f"error: --spp {spp} is not a multiple of the pass size {per_pass}")
    if a.out.exists() and any(a.out.iterdir()) and not a.overwrite:
        sys.exit(f"error: {a.out} exists and is not empty; pass --overwrite to replace it")
    a.out.mkdir(parents=True, exist_ok=True)

    med = desc["medium"]
    enc = med["mitsuba_encoding"]
    cam = dict(desc["camera"])
    if a.res is not None:
        cam["width"] = cam["height"] = a.res
    integ = dict(desc["integrator"])
    if a.max_depth is not None:
        integ["max_depth"] = a.max_depth
    if a.rr_depth is not None:
        integ["rr_depth"] = a.rr_depth
    light = desc["light"]
    mesh = a.ref / desc["shape"]["mesh_file"]
    scene = {
        "type": "scene",
        "integrator": {"type": "volpath", "max_depth": integ["max_depth"], "rr_depth": integ["rr_depth"]},
        "object": {
            "type": "ply",
            "filename": str(mesh),
            "face_normals": True,
            "bsdf": {"type": "null"},
            "interior": {
                "type": "homogeneous",
                "sigma_t": {"type": "rgb", "value": enc["sigma_t_rgb"]},
                "scale": enc["scale"],
                "albedo": {"type": "rgb", "value": med["albedo"]},
                "phase": {"type": "isotropic"},
            },
        },
    }
    sensors = []
    for v in desc["views"]:
        lp = v.get("light_position", light.get("position"))
        sensors.append(
            (
                v,
                lp,
                mi.load_dict(
                    sensor_dict(
                        cam["fov_deg"],
                        cam["fov_axis"],
                        mi.ScalarTransform4f(v["to_world"]),
                        cam["width"],
                        cam["height"],
                        per_pass,
                        clip=(cam["near_clip"], cam["far_clip"]),
                    )
                ),
            )
        )
    total = 0.0
    per_view = []
    scenes = {}
    for v, lp, sensor in sensors:
        key = tuple(lp)
        if key not in scenes:
            d = dict(scene)
            d["light"] = {
                "type": "point",
                "position": lp,
                "intensity": {"type": "rgb", "value": light["intensity_rgb"]},
            }
            scenes[key] = mi.load_dict(d)
        t0 = time.perf_counter()
        passes = spp // per_pass
        arr = 0.0
        for k in range(passes):
            # One seed per pass (distinct across seeds and passes).
            img = mi.render(scenes[key], sensor=sensor, spp=per_pass, seed=(a.seed * 1_000_003 + k) & 0xFFFF_FFFF)
            arr = arr + mi.TensorXf(img).numpy() / passes
        dt = time.perf_counter() - t0
        total += dt
        per_view.append(dt)
        mi.Bitmap(arr).write(str(a.out / v["file_exr"]))
        m = arr.reshape(-1, 3).mean(axis=0)
        print(f"view {v['index']}: {dt:.3f} s, mean RGB = ({m[0]:.5f}, {m[1]:.5f}, {m[2]:.5f})", flush=True)
    n = len(sensors)
    times = sorted(per_view)
    print(
        f"{n} views {cam['width']}x{cam['height']} at {spp} spp, seed {a.seed}, {a.variant}: {total:.2f} s "
        f"({total / n:.3f} s/view; median {times[n // 2]:.3f}, fastest {times[0]:.3f})"
    )
    out_desc = dict(desc)
    out_desc["generator"] = f"tools/mitsuba/render_reference.py (Mitsuba {mi.__version__}, {a.variant}), seed {a.seed}"
    out_desc["render"] = dict(desc["render"], spp=spp)
    out_desc["integrator"] = integ
    out_desc["camera"] = cam
    (a.out / "scene.json").write_text(json.dumps(out_desc, indent=1))
    shutil.copy(mesh, a.out / mesh.name)


if __name__ == "__main__":
    main()
