#!/usr/bin/env python3
"""Render every sensor of a Mitsuba 3 scene file into OUT/view_XXX.exr (linear RGB), the images
`translucent render SCENE.xml` writes for the same file, so that `translucent compare` holds our
reading of the file (and our tracer) against Mitsuba's own.

`--example DIR` first writes an example scene into DIR (an icosphere mesh, object.ply, placed by a
`to_world` of rotate, scale and translate; a GGX `roughdielectric` with int_ior "water" around an
HG medium; five sensors with fov along x, along y, along the diagonal, with an off-centre
principal point and by a focal length; a
gaussian reconstruction filter; one point light) and renders that.

    python3 tools/mitsuba/render_xml.py --example /tmp/xml-check --spp 1024 --out /tmp/xml-check/mitsuba
    translucent render /tmp/xml-check/scene.xml --spp 1024 --out /tmp/xml-check/ours
    translucent compare /tmp/xml-check/ours /tmp/xml-check/mitsuba
"""

import argparse
import os
import sys
import time
from pathlib import Path

EXAMPLE = """<scene version="3.0.0">
    <default name="spp" value="64"/>
    <integrator type="volpath"><integer name="max_depth" value="64"/></integrator>
    <bsdf type="roughdielectric" id="surface">
        <string name="distribution" value="ggx"/>
        <float name="alpha" value="0.2"/>
        <string name="int_ior" value="water"/>
    </bsdf>
    <sensor type="perspective">
        <float name="fov" value="35"/>
        <transform name="to_world"><lookat origin="0, 0.6, 2.5" target="0.1, 0, 0" up="0, 1, 0"/></transform>
        <sampler type="independent"><integer name="sample_count" value="$spp"/></sampler>
        <film type="hdrfilm"><integer name="width" value="64"/><integer name="height" value="48"/></film>
    </sensor>
    <sensor type="perspective">
        <float name="fov" value="30"/>
        <string name="fov_axis" value="y"/>
        <transform name="to_world"><lookat origin="2.4, 0.2, 0.4" target="0.1, 0, 0" up="0, 1, 0"/></transform>
        <film type="hdrfilm"><integer name="width" value="64"/><integer name="height" value="48"/></film>
    </sensor>
    <sensor type="perspective">
        <float name="fov" value="45"/>
        <string name="fov_axis" value="diagonal"/>
        <transform name="to_world"><lookat origin="-1.5, 1.5, 1.5" target="0.1, 0, 0" up="0, 1, 0"/></transform>
        <film type="hdrfilm"><integer name="width" value="48"/><integer name="height" value="64"/></film>
    </sensor>
    <sensor type="perspective">
        <float name="fov" value="35"/>
        <float name="principal_point_offset_x" value="0.15"/>
        <float name="principal_point_offset_y" value="-0.1"/>
        <transform name="to_world"><lookat origin="0.4, 0.5, 2.4" target="0.1, 0, 0" up="0, 1, 0"/></transform>
        <film type="hdrfilm"><integer name="width" value="64"/><integer name="height" value="48"/></film>
    </sensor>
    <sensor type="perspective">
        <string name="focal_length" value="70mm"/>
        <transform name="to_world"><lookat origin="0.3, -2.2, -1.4" target="0.1, 0, 0" up="0, 1, 0"/></transform>
        <film type="hdrfilm"><integer name="width" value="64"/><integer name="height" value="64"/></film>
    </sensor>
    <emitter type="point">
        <point name="position" x="1.2" y="1.6" z="1.4"/>
        <rgb name="intensity" value="6, 5, 4"/>
    </emitter>
    <shape type="ply">
        <string name="filename" value="object.ply"/>
        <transform name="to_world">
            <rotate y="1" angle="30"/>
            <scale x="1.2" y="0.8" z="1"/>
            <translate x="0.1"/>
        </transform>
        <ref id="surface"/>
        <medium type="homogeneous" name="interior">
            <rgb name="sigma_t" value="0.6, 0.8, 1"/>
            <float name="scale" value="25"/>
            <rgb name="albedo" value="0.95, 0.9, 0.8"/>
            <phase type="hg"><float name="g" value="0.6"/></phase>
        </medium>
    </shape>
</scene>
"""


def icosphere_ply(path, radius=0.5, subdivisions=4):
    """An icosphere as ASCII PLY (vertices on the sphere, outward counter-clockwise faces)."""
    t = (1.0 + 5.0 ** 0.5) / 2.0
    verts = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t),
             (0, -1, -t), (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
             (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
             (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]

    def unit(v):
        n = sum(c * c for c in v) ** 0.5
        return tuple(c / n for c in v)

    verts = [unit(v) for v in verts]
    for _ in range(subdivisions):
        cache, out = {}, []

        def mid(a, b):
            key = (min(a, b), max(a, b))
            if key not in cache:
                verts.append(unit(tuple((p + q) / 2 for p, q in zip(verts[a], verts[b]))))
                cache[key] = len(verts) - 1
            return cache[key]

        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            out += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = out
    lines = ["ply", "format ascii 1.0", f"element vertex {len(verts)}", "property float x",
             "property float y", "property float z", f"element face {len(faces)}",
             "property list uchar int vertex_indices", "end_header"]
    lines += [" ".join(f"{radius * c:.7f}" for c in v) for v in verts]
    lines += [f"3 {a} {b} {c}" for a, b, c in faces]
    Path(path).write_text("\n".join(lines) + "\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene", type=Path, nargs="?", help="Mitsuba 3 scene file (omit with --example)")
    ap.add_argument("--example", type=Path, help="write the example scene into this folder and render it")
    ap.add_argument("--out", type=Path, required=True, help="output folder (view_XXX.exr)")
    ap.add_argument("--spp", type=int, default=1024, help="samples per pixel (default 1024)")
    ap.add_argument("--seed", type=int, default=0, help="seed of view 0; view i uses seed + i")
    ap.add_argument("--variant", default="llvm_ad_rgb", help="Mitsuba variant (an RGB one)")
    a = ap.parse_args()
    if a.example:
        a.example.mkdir(parents=True, exist_ok=True)
        icosphere_ply(a.example / "object.ply")
        (a.example / "scene.xml").write_text(EXAMPLE)
        a.scene = a.example / "scene.xml"
    if a.scene is None:
        sys.exit("give a scene file, or --example DIR")
    llvm = "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1"
    if "DRJIT_LIBLLVM_PATH" not in os.environ and os.path.exists(llvm):
        os.environ["DRJIT_LIBLLVM_PATH"] = llvm
    import mitsuba as mi

    mi.set_variant(a.variant)
    scene = mi.load_file(str(a.scene))
    a.out.mkdir(parents=True, exist_ok=True)
    for i, _ in enumerate(scene.sensors()):
        t0 = time.time()
        img = mi.render(scene, sensor=i, spp=a.spp, seed=(a.seed + i) & 0xFFFF_FFFF)
        mi.util.write_bitmap(str(a.out / f"view_{i:03}.exr"), img)
        print(f"view {i}: {time.time() - t0:.1f} s", flush=True)
    print(f"wrote {a.out} ({a.spp} spp, Mitsuba {mi.__version__}, {a.variant})")


if __name__ == "__main__":
    main()
