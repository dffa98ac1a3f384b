#!/usr/bin/env python3
"""Render a translucent dataset's views with Mitsuba 3's own `volpath`: the same object, medium,
cameras and lights as DATASET (dataset.json, DATASET.md), new images by an independent renderer.

    pip install mitsuba numpy                # Mitsuba 3.9.1 + Dr.Jit 1.5.0 wheels
    apt-get install -y libllvm19             # the llvm_* variants need libLLVM (15 crashes; 19 works)
    python3 tools/mitsuba/render_dataset.py DATASET --out OUT --spp 128 --seed 0 \
        [--max-depth 128] [--spp-per-pass 32] [--variant llvm_ad_rgb] [--threads N]

DATASET's images are not read (a layout without meaningful images works). OUT receives
view_XXX.exr (linear float32 RGB, the camera's resolution), a copy of the mesh, and dataset.json:
DATASET's, with `render` replaced by {spp, seed, max_depth, renderer} and `generator` naming this
script. OUT is then a dataset for `translucent optimize --dataset OUT` (PNG previews are not
written; `translucent experiment robustness --targets mitsuba` adds them).

The scene follows prb_optimize.py and render_reference.py: the mesh (a mesh file, or the
built-in blob / sphere rebuilt exactly as the geometry crate builds it), a `null` boundary BSDF
(a `dielectric` when the object has eta > 1, a GGX `roughdielectric` when it is rough: the
dataset's `object` block, else its truth), a homogeneous interior medium with the truth's RGB
sigma_t and albedo and the object's phase function, one point light moved to each view's light, one perspective sensor per
view (fov along x, box filter, independent sampler), integrator `volpath` with rr_depth 5.
A medium with a g per channel (Mitsuba's hg has one g for all channels) is rendered once per
distinct g, and each channel of the images comes from the render at its own g: channel c of a
homogeneous medium depends on that channel's sigma_t, albedo and g alone.
Seeds: view i, pass k renders with seed ((seed * 1_000_003 + i) * 4096 + k) mod 2^32 (Mitsuba's
seeds are 32-bit).
Not used by the tests or CI: Mitsuba is a reference, not a dependency.
"""
import argparse
import json
import os
import shutil
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from prb_optimize import LLVM_CANDIDATES, builtin_mesh, load_dataset, loaded_llvm, scene_dict, write_ply  # noqa: E402
from render_reference import sensor_dict  # noqa: E402


def load_mitsuba(a):
    """Mitsuba with --variant set (libLLVM found for the llvm variants), or exit with the reason."""
    if a.variant.startswith("llvm") and "DRJIT_LIBLLVM_PATH" not in os.environ:
        for c in LLVM_CANDIDATES:
            if os.path.exists(c):
                os.environ["DRJIT_LIBLLVM_PATH"] = c
                break
    try:
        import drjit as dr
        import mitsuba as mi

        mi.set_variant(a.variant)
    except Exception as e:  # ImportError, or a variant the installed build or libLLVM lacks
        sys.exit(f"error: Mitsuba 3 ({a.variant}) cannot be loaded: {e}")
    if a.variant.startswith("llvm") and a.threads is not None:
        dr.set_thread_count(a.threads)
    return mi


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dataset", type=Path, nargs="?", help="dataset folder (dataset.json)")
    ap.add_argument("--out", type=Path)
    ap.add_argument("--check", action="store_true", help="only load Mitsuba, print its version and exit")
    ap.add_argument("--spp", type=int, default=128)
    ap.add_argument("--spp-per-pass", type=int, default=32, help="samples per render call (memory)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--max-depth", type=int, default=None, help="default: the dataset's, else 64")
    ap.add_argument("--rr-depth", type=int, default=5)
    ap.add_argument("--variant", default="llvm_ad_rgb")
    ap.add_argument("--threads", type=int, default=None, help="Dr.Jit threads (llvm; default: all cores)")
    ap.add_argument("--overwrite", action="store_true")
    a = ap.parse_args()
    if a.check:
        mi = load_mitsuba(a)
        print(f"Mitsuba {mi.__version__} ({a.variant}, libLLVM {loaded_llvm()})")
        return
    if a.dataset is None or a.out is None:
        ap.error("DATASET and --out are required")

    if a.spp < 1 or a.spp_per_pass < 1:
        sys.exit("error: --spp and --spp-per-pass must be >= 1")
    per_pass = min(a.spp, a.spp_per_pass)
    if a.spp % per_pass:
        sys.exit(f"error: --spp {a.spp} is not a multiple of --spp-per-pass {per_pass}")
    src = a.dataset / "dataset.json"
    if not src.is_file():
        sys.exit(f"error: {src}: not found (a translucent dataset folder holds dataset.json; see DATASET.md)")
    raw = json.loads(src.read_text())
    ds = load_dataset(a.dataset)
    truth = ds["truth"]
    if truth is None:
        sys.exit(f"error: {src}: field 'truth' is missing; the medium to render comes from it")
    if a.out.resolve() == a.dataset.resolve():
        sys.exit("error: --out must differ from the dataset folder")
    if a.out.exists() and any(a.out.iterdir()) and not a.overwrite:
        sys.exit(f"error: {a.out} exists and is not empty; pass --overwrite to replace it")
    a.out.mkdir(parents=True, exist_ok=True)

    mi = load_mitsuba(a)
    import drjit as dr

    if ds["mesh"] is not None:
        mesh_path = ds["mesh"]
        out_mesh = a.out / mesh_path.name
        if out_mesh.resolve() != mesh_path.resolve():
            shutil.copy(mesh_path, out_mesh)
        raw["mesh"] = mesh_path.name
    else:
        pos, faces = builtin_mesh(ds["shape"])
        out_mesh = a.out / "mesh.ply"
        write_ply(out_mesh, pos, faces)
        raw.pop("shape", None)
        raw["mesh"] = out_mesh.name
    mesh_type = out_mesh.suffix.lower().lstrip(".")
    if mesh_type not in ("ply", "obj"):
        sys.exit(f"error: {mesh_path}: mesh must be .ply or .obj")

    g, eta = truth["g"], truth["eta"]
    if eta != 1.0 and truth["roughness"] == 0.0:
        # A point light seen through a smooth dielectric is a delta connection: volpath's
        # next-event estimation is blocked by the boundary and no sampled path can hit the
        # light, so every view would render black (translucent connects it by manifold NEE).
        sys.exit(
            f"error: {src}: a smooth dielectric boundary (eta {eta}, roughness 0) lit by a point "
            "light renders black in Mitsuba 3's volpath (no path reaches the light through the "
            "smooth surface); render such a dataset with translucent, or state a rough boundary"
        )
    max_depth = a.max_depth or ds["max_depth"] or 64
    scale = max(truth["sigma_t"])
    v0 = ds["views"][0]
    # One render per distinct g; channel c of the images from the render at g_c.
    gs = g if isinstance(g, list) else [g] * 3
    passes_g = sorted(set(gs))
    print(
        f"Mitsuba {mi.__version__} ({a.variant}), libLLVM {loaded_llvm()}; {len(ds['views'])} views, "
        f"{a.spp} spp, max_depth {max_depth}, rr_depth {a.rr_depth}, seed {a.seed}"
        + (f", g per channel {gs}: one render per g" if len(passes_g) > 1 else ""),
        flush=True,
    )
    images = [None] * len(ds["views"])
    total = 0.0
    for g_pass in passes_g:
        scene = mi.load_dict(
            scene_dict(
                "volpath",
                max_depth,
                a.rr_depth,
                v0,
                mesh_type,
                out_mesh,
                eta,
                g_pass,
                truth["sigma_t"],
                truth["albedo"],
                scale,
                roughness=truth["roughness"],
            )
        )
        params = mi.traverse(scene)
        k_lp, k_li = "light.position", "light.intensity.value"
        for k in (k_lp, k_li):
            if k not in params:
                sys.exit(f"error: scene parameter {k!r} not found (Mitsuba {mi.__version__})")
        channels = [c for c in range(3) if gs[c] == g_pass]
        for i, v in enumerate(ds["views"]):
            params[k_lp] = dr.opaque(mi.Point3f, v["light_position"])
            params[k_li] = dr.opaque(mi.Color3f, v["intensity"])
            params.update()
            sensor = mi.load_dict(
                sensor_dict(
                    v["fov"], v["fov_axis"], mi.ScalarTransform4f(v["to_world"]), v["width"], v["height"],
                    per_pass, offset=v["principal_point_offset"],
                )
            )
            t0 = time.perf_counter()
            passes = a.spp // per_pass
            arr = 0.0
            for k in range(passes):
                img = mi.render(scene, sensor=sensor, spp=per_pass, seed=((a.seed * 1_000_003 + i) * 4096 + k) & 0xFFFF_FFFF)
                arr = arr + mi.TensorXf(img).numpy() / passes
            dt = time.perf_counter() - t0
            total += dt
            if images[i] is None:
                images[i] = arr.copy()
            images[i][..., channels] = arr[..., channels]
            m = arr.reshape(-1, 3).mean(axis=0)
            print(f"view {i} (g {g_pass}): {dt:.2f} s, mean RGB = ({m[0]:.5f}, {m[1]:.5f}, {m[2]:.5f})", flush=True)
    for i, rv in enumerate(raw["views"]):
        name = f"view_{i:03d}.exr"
        mi.Bitmap(images[i]).write(str(a.out / name))
        rv["image"] = name
    raw["render"] = {
        "spp": a.spp,
        "max_depth": max_depth,
        "seed": a.seed,
        "renderer": f"Mitsuba {mi.__version__} volpath ({a.variant}), rr_depth {a.rr_depth}",
    }
    raw["generator"] = "tools/mitsuba/render_dataset.py"
    tmp = a.out / "dataset.json.tmp"
    tmp.write_text(json.dumps(raw, indent=2))
    tmp.replace(a.out / "dataset.json")  # last, so that a complete folder is the only one with it
    print(f"{len(ds['views'])} views in {total:.1f} s -> {a.out}")


if __name__ == "__main__":
    main()
