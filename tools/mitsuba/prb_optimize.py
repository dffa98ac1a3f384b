#!/usr/bin/env python3
"""Baseline for `translucent optimize`: recover a homogeneous medium (per-channel extinction sigma_t
and single-scattering albedo, RGB) from a dataset's images with Mitsuba 3's own differentiable
volumetric path tracer `prbvolpath` and Adam, and report seconds per iteration to compare side by
side with ours.

    pip install mitsuba numpy                # Mitsuba 3.9.1 + Dr.Jit 1.5.0 wheels
    apt-get install -y libllvm19             # the llvm_* variants need libLLVM (15 crashes; 19 works)
    python3 tools/mitsuba/prb_optimize.py DATASET --iterations 300 --spp 32 --views-per-iter 1 \
        --init-sigma-t 50 --init-albedo 0.5 --lr-sigma-t 0.015 --lr-albedo 0.02 --seed 0 \
        --out OUT [--variant llvm_ad_rgb] [--threads N]

DATASET is a dataset folder (dataset.json + mesh or built-in shape + view_XXX.exr, DATASET.md) or
a Mitsuba reference-render folder (scene.json, as render_reference.py's input). One Mitsuba scene
holds the object (mesh file, or the built-in `blob` / `sphere` rebuilt here exactly as the
geometry crate builds it and written to OUT/mesh.ply), a `null` boundary BSDF (eta = 1; a
`dielectric` if the truth says eta > 1, a GGX `roughdielectric` when it has a roughness), a
homogeneous interior medium with RGB sigma_t and
albedo (HG phase with the truth's g), one point light and one perspective sensor per view (fov
along x, box filter, hdrfilm rgb, independent sampler), integrator `prbvolpath` with the dataset's
max_depth (64 if not given) and rr_depth 5 (both as translucent's volpath). These are the same
conventions as render_reference.py.

Each iteration picks --views-per-iter distinct views at random (Python's random.Random(--seed)),
moves the light to each view's light (scene parameter `light.position`/`light.intensity`),
renders with `spp` samples per pixel, takes the L2 loss (mean over pixels and channels of the
squared difference to the target; averaged over the views) and back-propagates through
prbvolpath; Adam (mi.ad.Adam = drjit.opt.Adam) updates ln(sigma_t) and albedo with their own
learning rates (both times --decay every --decay-every iterations; by default constant), and albedo
is clamped to [1e-4, 0.99995] after each step.

Prints every --print-every iterations: iteration, view(s), loss, sigma_t, albedo, seconds of the
iteration and the kernels Dr.Jit had to compile in it (cache misses). At the end: the mean seconds
per iteration over iterations 1..N-1 (the first includes the JIT compilation of the kernels), the
median, and the final estimate against the truth. Writes OUT/iterations.csv (one row per
iteration) and OUT/result.json (estimate, truth, seconds_per_iteration, spp, iterations, variant,
Mitsuba/Dr.Jit versions, libLLVM loaded, CPU count, threads).

Each iteration's time is wall clock from the start of the iteration until the new parameters and
the loss are back on the host (the renders, the backward pass and the Adam step have all run).
Kernels are compiled in iteration 0 (or loaded from Dr.Jit's disk cache ~/.drjit on later runs);
the light and the medium are opaque parameters, so later iterations reuse them (a small kernel or
two may still compile once in the first few iterations: column kernels_compiled of the CSV).
Not used by the tests or CI: Mitsuba is a reference, not a dependency.
"""
import argparse
import csv
import json
import math
import os
import platform
import random
import statistics
import struct
import sys
import time
from pathlib import Path

import numpy as np

# The camera conventions of the reference renders (same folder; run as a script, so importable).
from render_reference import sensor_dict

ALBEDO_MIN, ALBEDO_MAX = 1e-4, 0.99995
# libLLVM candidates (Debian's libllvm19 first). Dr.Jit's llvm back end crashes with LLVM 15.
LLVM_CANDIDATES = [
    "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1",
    "/usr/lib/x86_64-linux-gnu/libLLVM-19.so",
    "/usr/lib/llvm-19/lib/libLLVM.so.1",
    "/usr/lib/llvm-19/lib/libLLVM-19.so",
    "/usr/lib/llvm-19/lib/libLLVM.so",
]


def rgb3(v, what):
    """One number or [r, g, b] -> [r, g, b] (floats)."""
    if isinstance(v, (int, float)):
        return [float(v)] * 3
    if isinstance(v, list) and len(v) == 3:
        return [float(x) for x in v]
    sys.exit(f"error: {what} = {v!r}: expected one number or [r, g, b]")


def g_of(v, what):
    """A Henyey-Greenstein g as written (one number, or [r, g, b] for a g per channel) -> one
    float where the channels share it, else the list of three."""
    g = rgb3(v, what)
    return g[0] if g[0] == g[1] == g[2] else g


def parse_rgb_arg(s, what):
    parts = [p for p in s.split(",") if p.strip()]
    if len(parts) not in (1, 3):
        sys.exit(f"error: {what} = {s!r}: expected one number or R,G,B")
    try:
        vals = [float(p) for p in parts]
    except ValueError:
        sys.exit(f"error: {what} = {s!r}: not a number")
    return vals * 3 if len(vals) == 1 else vals


def look_at(origin, target, up):
    """Mitsuba's look_at as a row-major 4x4 list (columns x = image left, y = up, z = view dir)."""
    o, t, u = (np.asarray(v, dtype=np.float64) for v in (origin, target, up))
    z = t - o
    z /= np.linalg.norm(z)
    x = np.cross(u, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = x, y, z, o
    return m.tolist()


# ---------------------------------------------------------------------------------------------
# Built-in shapes (crates/geometry/src/shapes/sphere.rs), so that datasets written with
# `translucent dataset --shape blob|sphere` (no mesh file) can be rendered by Mitsuba.


def _icosphere(subdivisions):
    t = (1.0 + 5.0**0.5) / 2.0
    base = [
        [-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
        [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1],
    ]  # fmt: skip
    verts = [np.asarray(p, dtype=np.float64) / np.linalg.norm(p) for p in base]
    faces = [
        [0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
        [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
        [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1],
    ]  # fmt: skip
    for _ in range(subdivisions):
        mids = {}

        def mid(a, b):
            key = (min(a, b), max(a, b))
            if key not in mids:
                m = verts[a] + verts[b]
                verts.append(m / np.linalg.norm(m))
                mids[key] = len(verts) - 1
            return mids[key]

        nxt = []
        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            nxt += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        faces = nxt
    return np.array(verts), np.array(faces, dtype=np.int32)


class _Pcg32:
    """rand_pcg 0.10 Lcg64Xsh32 seeded by rand_core 0.10's seed_from_u64."""

    M64 = (1 << 64) - 1
    MUL = 6364136223846793005

    def __init__(self, seed):
        state, words = seed & self.M64, []
        for _ in range(4):  # rand_core::SeedableRng::seed_from_u64: PCG32 fills the 16-byte seed
            state = (state * 0x5851F42D4C957F2D + 0xA17654E46FBE17F3) & self.M64
            words.append(self._out(state))
        s0 = words[0] | (words[1] << 32)
        s1 = words[2] | (words[3] << 32)
        self.inc = s1 | 1
        self.state = (s0 + self.inc) & self.M64
        self._step()

    @staticmethod
    def _out(state):
        xs = (((state >> 18) ^ state) >> 27) & 0xFFFFFFFF
        rot = state >> 59
        return ((xs >> rot) | (xs << ((32 - rot) & 31))) & 0xFFFFFFFF

    def _step(self):
        self.state = (self.state * self.MUL + self.inc) & self.M64

    def next_u32(self):
        s = self.state
        self._step()
        return self._out(s)

    def uniform(self):
        return (self.next_u32() + 0.5) / 4294967296.0


def builtin_mesh(spec):
    """(positions float32 [n, 3], faces int32 [m, 3]) of a built-in shape spec from dataset.json."""
    name = spec.get("name")
    if name == "sphere":
        dirs, faces = _icosphere(int(spec.get("subdivisions", 5)))
        return (dirs * float(spec.get("radius", 0.5))).astype(np.float32), faces
    if name in ("blob", "bumpy-blob"):
        radius = float(spec.get("radius", 0.5))
        amplitude = float(spec.get("amplitude", 0.15))
        rng = _Pcg32(int(spec.get("seed", 7)))
        bumps = []
        for _ in range(int(spec.get("bumps", 12))):
            z = 2.0 * rng.uniform() - 1.0
            phi = 2.0 * math.pi * rng.uniform()
            s = math.sqrt(max(1.0 - z * z, 0.0))
            centre = [s * math.cos(phi), z, s * math.sin(phi)]
            sign = -1.0 if rng.uniform() < 0.5 else 1.0
            magnitude = 0.5 + 0.5 * rng.uniform()
            width = 0.2 + 0.3 * rng.uniform()
            bumps.append((centre, sign * magnitude, 1.0 / (width * width)))
        dirs, faces = _icosphere(int(spec.get("subdivisions", 6)))
        total = np.zeros(len(dirs))
        for centre, weight, inv_w2 in bumps:
            total += weight * np.exp(-(1.0 - dirs @ np.asarray(centre)) * inv_w2)
        pos = (dirs * (radius * np.exp(amplitude * total))[:, None]).astype(np.float32)
        centre = np.float32(0.5) * (pos.min(axis=0) + pos.max(axis=0))  # bbox centred on the origin
        return (pos - centre).astype(np.float32), faces
    sys.exit(
        f"error: built-in shape {name!r} is not rebuilt by this script (only blob and sphere); "
        "give its mesh with --mesh FILE, or make the dataset from a mesh file (`translucent dataset --mesh FILE`)"
    )


def write_ply(path, pos, faces):
    head = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(pos)}\nproperty float x\nproperty float y\nproperty float z\n"
        f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    rec = np.zeros(len(faces), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    rec["n"], rec["i"] = 3, faces
    with open(path, "wb") as f:
        f.write(head.encode("ascii"))
        f.write(np.ascontiguousarray(pos, dtype="<f4").tobytes())
        f.write(rec.tobytes())


# ---------------------------------------------------------------------------------------------
# Dataset loading: dataset.json (DATASET.md) or a Mitsuba reference folder (scene.json).


def _to_world(c):
    """A camera's to_world matrix: given, or from origin/target/up."""
    if "to_world" in c:
        return c["to_world"]
    return look_at(c["origin"], c["target"], c.get("up", [0.0, 1.0, 0.0]))


def _view(c, fov, fov_axis, width, height, light_position, intensity, image, offset=(0.0, 0.0)):
    return dict(
        to_world=_to_world(c),
        fov=float(fov),
        fov_axis=fov_axis,
        principal_point_offset=offset,
        width=int(width),
        height=int(height),
        light_position=[float(x) for x in light_position],
        intensity=intensity,
        image=image,
    )


def load_dataset(folder):
    """-> dict(mesh=path or None, shape=spec or None, truth=dict or None, max_depth, views=[...])
    with each view {to_world, fov, fov_axis, width, height, light_position, intensity, image}."""
    if (folder / "dataset.json").is_file():
        d = json.loads((folder / "dataset.json").read_text())
        if d.get("format") != "translucent-dataset":
            sys.exit(f"error: {folder}/dataset.json: format is not 'translucent-dataset'")
        views = []
        for i, v in enumerate(d["views"]):
            c, l = v["camera"], v["light"]
            fov, offset = c.get("fov_x_deg"), (0.0, 0.0)
            if "intrinsics" in c:
                # A calibrated camera (DATASET.md): Mitsuba's principal-point offsets are
                # fractions of the film, the optical axis meeting it at 1/2 - offset.
                k = c["intrinsics"]
                if abs(k["fy"] / k["fx"] - 1.0) > 1e-6:
                    sys.exit(
                        f"error: {folder}/dataset.json: views[{i}].camera.intrinsics: fy != fx "
                        "(non-square pixels) has no Mitsuba perspective sensor"
                    )
                fov = math.degrees(2.0 * math.atan(0.5 * c["width"] / k["fx"]))
                offset = (0.5 - k["cx"] / c["width"], 0.5 - k["cy"] / c["height"])
            views.append(
                _view(
                    c,
                    fov,
                    "x",
                    c["width"],
                    c["height"],
                    l["position"],
                    rgb3(l["intensity"], f"views[{i}].light.intensity"),
                    folder / v["image"],
                    offset,
                )
            )
        truth = d.get("truth")
        if truth is not None:
            truth = dict(
                sigma_t=rgb3(truth["sigma_t"], "truth.sigma_t"),
                albedo=rgb3(truth["albedo"], "truth.albedo"),
                g=g_of(truth.get("g", 0.0), "truth.g"),
                eta=float(truth.get("eta", 1.0)),
                roughness=float(truth.get("roughness", 0.0)),
            )
            # What the dataset states about the object (boundary, phase function) is the
            # physics to render; translucent refuses a truth that contradicts it.
            obj = d.get("object")
            if obj is not None:
                b, ph = obj.get("boundary", {}), obj.get("phase", {})
                if b.get("type") == "dielectric":
                    truth["eta"] = float(b["eta"])
                    truth["roughness"] = float(b.get("roughness", 0.0))
                elif b.get("type") == "null":
                    truth["eta"], truth["roughness"] = 1.0, 0.0
                truth["g"] = g_of(ph["g"], "object.phase.g") if ph.get("type") == "hg" else 0.0
        return dict(
            mesh=folder / d["mesh"] if "mesh" in d else None,
            shape=d.get("shape"),
            truth=truth,
            max_depth=d.get("render", {}).get("max_depth"),
            views=views,
        )
    if (folder / "scene.json").is_file():
        d = json.loads((folder / "scene.json").read_text())
        cam, light, med = d["camera"], d["light"], d["medium"]
        inten = rgb3(light.get("intensity_rgb", light.get("intensity")), "light.intensity_rgb")
        views = []
        for v in d["views"]:
            views.append(
                _view(
                    v,
                    cam["fov_deg"],
                    cam.get("fov_axis", "x"),
                    cam["width"],
                    cam["height"],
                    v.get("light_position", light.get("position")),
                    inten,
                    folder / v["file_exr"],
                )
            )
        b = d.get("boundary", {})
        eta = 1.0
        if b.get("bsdf") == "dielectric":
            eta = float(b.get("int_ior", 1.0)) / float(b.get("ext_ior", 1.0))
        truth = dict(
            sigma_t=rgb3(med["sigma_t"], "medium.sigma_t"),
            albedo=rgb3(med["albedo"], "medium.albedo"),
            g=float(med.get("phase", {}).get("g", 0.0)),
            eta=eta,
        )
        return dict(
            mesh=folder / d["shape"]["mesh_file"],
            shape=None,
            truth=truth,
            max_depth=d.get("integrator", {}).get("max_depth"),
            views=views,
        )
    sys.exit(f"error: {folder}: no dataset.json (or scene.json); see DATASET.md")


def scene_dict(
    integrator, max_depth, rr_depth, view, mesh_type, mesh_path, eta, g, sigma_t, albedo, scale, roughness=0.0
):
    """Mitsuba's description of one of our datasets' scenes: the mesh with a `null` boundary
    (a `dielectric` for eta != 1, a GGX `roughdielectric` of alpha `roughness` when it is > 0)
    around a homogeneous medium (RGB sigma_t stored as sigma_t / scale with `scale`, since 'rgb'
    values must lie in [0, 1] when loaded; HG phase with g), one point light at `view`'s light,
    and `integrator` (volpath or prbvolpath)."""
    if eta == 1.0:
        boundary = {"type": "null"}
    elif roughness == 0.0:
        boundary = {"type": "dielectric", "int_ior": eta, "ext_ior": 1.0}
    else:
        boundary = {
            "type": "roughdielectric",
            "distribution": "ggx",
            "alpha": roughness,
            "int_ior": eta,
            "ext_ior": 1.0,
        }
    return {
        "type": "scene",
        "integrator": {"type": integrator, "max_depth": max_depth, "rr_depth": rr_depth},
        "light": {
            "type": "point",
            "position": view["light_position"],
            "intensity": {"type": "rgb", "value": view["intensity"]},
        },
        "object": {
            "type": mesh_type,
            "filename": str(mesh_path),
            "face_normals": True,
            "bsdf": boundary,
            "interior": {
                "type": "homogeneous",
                "sigma_t": {"type": "rgb", "value": [x / scale for x in sigma_t]},
                "scale": scale,
                "albedo": {"type": "rgb", "value": list(albedo)},
                "phase": {"type": "isotropic"} if g == 0.0 else {"type": "hg", "g": g},
            },
        },
    }


def loaded_llvm():
    try:
        for line in open("/proc/self/maps"):
            if "libLLVM" in line:
                return line.split()[-1]
    except OSError:
        pass
    return None


def fmt3(v, f="{:.4f}"):
    return "(" + ", ".join(f.format(x) for x in v) + ")"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dataset", type=Path, help="dataset folder (dataset.json) or reference folder (scene.json)")
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument(
        "--mesh",
        type=Path,
        default=None,
        help="the object's mesh (.ply/.obj) in place of the dataset's: for a built-in shape this script does not rebuild",
    )
    ap.add_argument("--iterations", type=int, default=300)
    ap.add_argument("--spp", type=int, default=32)
    ap.add_argument("--views-per-iter", type=int, default=1)
    ap.add_argument("--init-sigma-t", default="50", help="one value or R,G,B (1/unit)")
    ap.add_argument("--init-albedo", default="0.5", help="one value or R,G,B")
    ap.add_argument("--lr-sigma-t", type=float, default=0.015, help="Adam step on ln(sigma_t)")
    ap.add_argument("--lr-albedo", type=float, default=0.02, help="Adam step on albedo")
    ap.add_argument(
        "--decay",
        type=float,
        default=1.0,
        help="both learning rates times this every --decay-every iterations (translucent optimize: 0.85 every 50)",
    )
    ap.add_argument("--decay-every", type=int, default=50)
    ap.add_argument("--seed", type=int, default=0, help="view choice and render seeds")
    ap.add_argument("--max-depth", type=int, default=None, help="default: the dataset's, else 64")
    ap.add_argument("--rr-depth", type=int, default=5)
    ap.add_argument("--variant", default="llvm_ad_rgb")
    ap.add_argument("--threads", type=int, default=None, help="Dr.Jit threads (llvm; default: all cores)")
    ap.add_argument("--print-every", type=int, default=1)
    ap.add_argument("--no-kernel-history", action="store_true", help="do not record JIT compilations")
    ap.add_argument("--overwrite", action="store_true")
    a = ap.parse_args()

    if a.iterations < 1 or a.spp < 1 or a.views_per_iter < 1 or a.print_every < 1:
        sys.exit("error: --iterations, --spp, --views-per-iter and --print-every must be >= 1")
    init_st = parse_rgb_arg(a.init_sigma_t, "--init-sigma-t")
    init_al = parse_rgb_arg(a.init_albedo, "--init-albedo")
    if min(init_st) <= 0:
        sys.exit("error: --init-sigma-t must be > 0")
    if not all(ALBEDO_MIN <= x <= ALBEDO_MAX for x in init_al):
        sys.exit(f"error: --init-albedo must lie in [{ALBEDO_MIN}, {ALBEDO_MAX}]")
    ds = load_dataset(a.dataset)
    if ds["truth"]["eta"] != 1.0 and ds["truth"]["roughness"] == 0.0:
        # Under a point light a smooth dielectric object is black in volpath and prbvolpath:
        # the one refracted path to the light is a delta connection neither can sample.
        sys.exit(
            f"error: {a.dataset}: a smooth dielectric boundary (eta {ds['truth']['eta']}) lit by a "
            "point light renders black in Mitsuba 3 (no path reaches the light through the smooth "
            "surface); this baseline needs an index-matched or rough boundary"
        )
    nv = len(ds["views"])
    if a.views_per_iter > nv:
        sys.exit(f"error: --views-per-iter {a.views_per_iter} > {nv} views in the dataset")
    if a.out.exists() and any(a.out.iterdir()) and not a.overwrite:
        sys.exit(f"error: {a.out} exists and is not empty; pass --overwrite to replace it")
    a.out.mkdir(parents=True, exist_ok=True)

    if a.variant.startswith("llvm") and "DRJIT_LIBLLVM_PATH" not in os.environ:
        for c in LLVM_CANDIDATES:
            if os.path.exists(c):
                os.environ["DRJIT_LIBLLVM_PATH"] = c
                break
    import drjit as dr
    import mitsuba as mi

    mi.set_variant(a.variant)
    if a.variant.startswith("llvm") and a.threads is not None:
        dr.set_thread_count(a.threads)

    # Geometry.
    if a.mesh is not None:
        mesh_path = a.mesh
    elif ds["mesh"] is not None:
        mesh_path = ds["mesh"]
    else:
        pos, faces = builtin_mesh(ds["shape"])
        mesh_path = a.out / "mesh.ply"
        write_ply(mesh_path, pos, faces)
    mesh_type = mesh_path.suffix.lower().lstrip(".")
    if mesh_type not in ("ply", "obj"):
        sys.exit(f"error: {mesh_path}: mesh must be .ply or .obj")

    truth = ds["truth"]
    g = truth["g"] if truth else 0.0
    if isinstance(g, list):
        sys.exit(
            f"error: the medium has a g per channel ({g}); Mitsuba 3's hg phase function has one "
            "g for every channel, so prbvolpath cannot render it"
        )
    eta = truth["eta"] if truth else 1.0
    max_depth = a.max_depth or ds["max_depth"] or 64
    # 'rgb' values must be in [0, 1] when loaded: sigma_t = rgb * scale; the optimiser later
    # writes sigma_t / scale into the parameter (no range check there).
    scale = max(init_st)
    v0 = ds["views"][0]
    scene = mi.load_dict(
        scene_dict(
            "prbvolpath",
            max_depth,
            a.rr_depth,
            v0,
            mesh_type,
            mesh_path,
            eta,
            g,
            init_st,
            init_al,
            scale,
            roughness=ds["truth"]["roughness"] if ds["truth"] else 0.0,
        )
    )
    sensors = [
        mi.load_dict(
            sensor_dict(
                v["fov"],
                v["fov_axis"],
                mi.ScalarTransform4f(v["to_world"]),
                v["width"],
                v["height"],
                a.spp,
                offset=v["principal_point_offset"],
            )
        )
        for v in ds["views"]
    ]
    targets = []
    for v in ds["views"]:
        bmp = mi.Bitmap(str(v["image"])).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32, srgb_gamma=False)
        arr = np.array(bmp, dtype=np.float32)
        if arr.shape != (v["height"], v["width"], 3):
            sys.exit(f"error: {v['image']}: image is {arr.shape}, camera is {v['height']}x{v['width']}x3")
        if not np.isfinite(arr).all():
            sys.exit(f"error: {v['image']}: non-finite pixels")
        targets.append(mi.TensorXf(arr))

    params = mi.traverse(scene)
    k_st = "object.interior_medium.sigma_t.value.value"
    k_al = "object.interior_medium.albedo.value.value"
    k_lp, k_li = "light.position", "light.intensity.value"
    for k in (k_st, k_al, k_lp, k_li):
        if k not in params:
            sys.exit(f"error: scene parameter {k!r} not found (Mitsuba {mi.__version__}): {list(params.keys())}")
    params.keep([k_st, k_al, k_lp, k_li])

    opt = mi.ad.Adam(lr=a.lr_albedo)
    opt["log_sigma_t"] = mi.Color3f([math.log(x) for x in init_st])
    opt["albedo"] = mi.Color3f(init_al)
    opt.set_learning_rate({"log_sigma_t": a.lr_sigma_t, "albedo": a.lr_albedo})

    def host3(c):
        return [float(x) for x in np.array(c).reshape(-1)[:3]]

    rng = random.Random(a.seed)
    kh = not a.no_kernel_history
    if kh:
        dr.set_flag(dr.JitFlag.KernelHistory, True)
        dr.kernel_history_clear()
    ncpu = os.cpu_count()
    print(
        f"Mitsuba {mi.__version__} ({a.variant}), Dr.Jit {dr.__version__}, libLLVM {loaded_llvm()}, "
        f"{ncpu} CPUs, threads {a.threads or 'default'}; {nv} views, max_depth {max_depth}, rr_depth "
        f"{a.rr_depth}, spp {a.spp}, {a.views_per_iter} view(s)/iteration, {a.iterations} iterations",
        flush=True,
    )
    if truth:
        print(f"truth: sigma_t = {fmt3(truth['sigma_t'], '{:.3f}')}, albedo = {fmt3(truth['albedo'])}")
    rows = []
    seen = set()
    for it in range(a.iterations):
        t0 = time.perf_counter()
        if a.decay != 1.0 and it > 0 and it % a.decay_every == 0:
            f = a.decay ** (it // a.decay_every)
            opt.set_learning_rate({"log_sigma_t": a.lr_sigma_t * f, "albedo": a.lr_albedo * f})
        vs = rng.sample(range(nv), a.views_per_iter)
        loss_total = 0.0
        for j, vi in enumerate(vs):
            v = ds["views"][vi]
            # Opaque (not literal) values, so that changing the light does not change the kernels.
            params[k_lp] = dr.opaque(mi.Point3f, v["light_position"])
            params[k_li] = dr.opaque(mi.Color3f, v["intensity"])
            params[k_st] = dr.exp(opt["log_sigma_t"]) / scale
            params[k_al] = opt["albedo"]
            params.update()
            img = mi.render(
                scene, params, sensor=sensors[vi], spp=a.spp, seed=((a.seed * 1_000_003 + it) * 64 + j) & 0xFFFF_FFFF
            )
            loss = dr.mean(dr.square(img - targets[vi]), axis=None) / len(vs)
            dr.backward(loss)
            loss_total += float(loss.array[0])
        opt.step()
        opt["albedo"] = dr.clip(opt["albedo"], ALBEDO_MIN, ALBEDO_MAX)
        st = [math.exp(x) for x in host3(opt["log_sigma_t"])]
        al = host3(opt["albedo"])
        dt = time.perf_counter() - t0
        compiled, from_disk, jit_ms = 0, 0, 0.0
        if kh:
            for k in dr.kernel_history([dr.KernelType.JIT]):
                if not k.get("cache_hit", True):  # compiled by LLVM now
                    compiled += 1
                    jit_ms += float(k.get("backend_time", 0.0))
                elif k.get("cache_disk", False):  # loaded from Dr.Jit's on-disk cache (~/.drjit)
                    from_disk += 1
        new_views = [x for x in vs if x not in seen]
        seen.update(vs)
        rows.append(
            dict(
                iteration=it,
                views=" ".join(map(str, vs)),
                loss=loss_total,
                sigma_t_r=st[0], sigma_t_g=st[1], sigma_t_b=st[2],
                albedo_r=al[0], albedo_g=al[1], albedo_b=al[2],
                seconds=dt,
                kernels_compiled=compiled if kh else "",
                kernels_from_disk_cache=from_disk if kh else "",
                compile_seconds=jit_ms / 1000.0 if kh else "",
                first_use_of_view=int(bool(new_views)),
            )  # fmt: skip
        )
        if it % a.print_every == 0 or it == a.iterations - 1:
            jit = f", compiled {compiled} kernel(s) in {jit_ms / 1000:.2f} s" if kh and compiled else ""
            jit += f", {from_disk} kernel(s) from the disk cache" if kh and from_disk else ""
            print(
                f"iter {it:4d} view {rows[-1]['views']}: loss {loss_total:.4e}  sigma_t {fmt3(st, '{:.3f}')}  "
                f"albedo {fmt3(al)}  {dt:.3f} s{jit}",
                flush=True,
            )
        if not math.isfinite(loss_total):
            print(f"warning: non-finite loss at iteration {it}", file=sys.stderr)

    with open(a.out / "iterations.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)
    later = [r["seconds"] for r in rows[1:]]
    spi = statistics.fmean(later) if later else float("nan")
    median = statistics.median(later) if later else float("nan")
    compiles_later = sum(r["kernels_compiled"] or 0 for r in rows[1:]) if kh else None
    print(
        f"seconds per iteration (iterations 1..{a.iterations - 1}): mean {spi:.4f}, median {median:.4f}; "
        f"iteration 0 (with JIT): {rows[0]['seconds']:.3f} s"
        + (f"; kernels compiled after iteration 0: {compiles_later}" if kh else "")
    )
    est = dict(sigma_t=[rows[-1][f"sigma_t_{c}"] for c in "rgb"], albedo=[rows[-1][f"albedo_{c}"] for c in "rgb"])
    print(f"estimate: sigma_t = {fmt3(est['sigma_t'], '{:.3f}')}, albedo = {fmt3(est['albedo'])}")
    rel = None
    if truth:
        rel = dict(
            sigma_t=[e / t - 1.0 for e, t in zip(est["sigma_t"], truth["sigma_t"])],
            albedo=[e / t - 1.0 for e, t in zip(est["albedo"], truth["albedo"])],
        )
        print(f"truth:    sigma_t = {fmt3(truth['sigma_t'], '{:.3f}')}, albedo = {fmt3(truth['albedo'])}")
        print(
            f"relative error: sigma_t {fmt3([100 * x for x in rel['sigma_t']], '{:+.1f}%')}, "
            f"albedo {fmt3([100 * x for x in rel['albedo']], '{:+.1f}%')}"
        )
    result = dict(
        method="Mitsuba 3 prbvolpath + Adam (tools/mitsuba/prb_optimize.py)",
        command=" ".join([Path(sys.argv[0]).name] + sys.argv[1:]),
        dataset=str(a.dataset),
        estimate=est,
        truth=truth,
        relative_error=rel,
        init=dict(sigma_t=init_st, albedo=init_al),
        final_loss=rows[-1]["loss"],
        seconds_per_iteration=spi,
        seconds_per_iteration_median=median,
        seconds_first_iteration=rows[0]["seconds"],
        seconds_per_iteration_note="mean wall-clock seconds over iterations 1..N-1 (iteration 0 "
        "includes JIT compilation, or loading the kernels from Dr.Jit's disk cache ~/.drjit); each "
        "includes render(s), backward pass, Adam step and host sync",
        kernels_compiled_first_iteration=rows[0]["kernels_compiled"] if kh else None,
        kernels_from_disk_cache_first_iteration=rows[0]["kernels_from_disk_cache"] if kh else None,
        kernels_compiled_after_first_iteration=compiles_later,
        spp=a.spp,
        iterations=a.iterations,
        views_per_iter=a.views_per_iter,
        views=nv,
        resolution=sorted({f"{v['width']}x{v['height']}" for v in ds["views"]}),
        lr=dict(log_sigma_t=a.lr_sigma_t, albedo=a.lr_albedo),
        lr_decay=dict(factor=a.decay, every=a.decay_every),
        seed=a.seed,
        integrator=dict(type="prbvolpath", max_depth=max_depth, rr_depth=a.rr_depth),
        boundary="null" if eta == 1.0 else "dielectric",
        variant=a.variant,
        mitsuba_version=mi.__version__,
        drjit_version=dr.__version__,
        libllvm=loaded_llvm() if a.variant.startswith("llvm") else None,
        python=platform.python_version(),
        cpu_count=ncpu,
        drjit_threads=dr.thread_count() if a.variant.startswith("llvm") else None,
        cpu_model=next(
            (l.split(":", 1)[1].strip() for l in open("/proc/cpuinfo") if l.startswith("model name")), None
        )
        if os.path.exists("/proc/cpuinfo")
        else platform.processor(),
    )
    (a.out / "result.json").write_text(json.dumps(result, indent=1))
    print(f"wrote {a.out / 'iterations.csv'} and {a.out / 'result.json'}")


if __name__ == "__main__":
    main()
