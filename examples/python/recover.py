"""The demo's job from Python: render a blob of a hidden medium, recover the medium from those
images with the product's defaults, print the estimate with its 95 % intervals, plot the fit.

    pip install ./python            # once, from the repository
    python examples/python/recover.py [--quick]
"""
import sys
from pathlib import Path

import translucent as tl

out = Path("out/python-example")
out.mkdir(parents=True, exist_ok=True)
quick = "--quick" in sys.argv
size, views = (32, 4) if quick else (64, 8)
(out / "scene.toml").write_text(f"""
shape = {{ name = "blob", scale = 0.5 }}
[medium]
sigma_t = [30.0, 45.0, 60.0]
albedo = [0.95, 0.90, 0.85]
[rig]
views = {views}
radius = 2.0
fov = 40.0
width = {size}
height = {size}
light = "fixed"
light_position = [1.0, 1.5, 0.5]
intensity = 4.0
""")
ds = tl.Dataset.from_scene(out / "scene.toml")                    # cameras, lights, mesh
targets = tl.render(ds, spp=64 if quick else 256, seed=1).images   # the "photographs"
ds = ds.with_images(targets).save(out / "dataset", overwrite=True)
result = tl.optimize(ds, out / "fit", overwrite=True, verbose=False,
                     **(dict(iterations=40, uncertainty_views=4) if quick else {}))
print("truth   ", ds.truth)
print(result)
try:
    import matplotlib.pyplot as plt
    import numpy as np
    it = np.genfromtxt(out / "fit" / "iterations.csv", delimiter=",", names=True)
    fig, ax = plt.subplots(1, 2, figsize=(9, 3.5))
    for c in "rgb":
        ax[0].plot(it["iteration"], it[f"sigma_t_{c}"], c)
        ax[1].plot(it["iteration"], it[f"albedo_{c}"], c)
    ax[0].set(xlabel="iteration", ylabel="σ_t"), ax[1].set(xlabel="iteration", ylabel="albedo")
    fig.savefig(out / "fit.png", dpi=120, bbox_inches="tight")
    print("plot:", out / "fit.png")
except ImportError:
    print("(matplotlib is not installed: no plot; the run's own is", out / "fit" / "convergence.png)")
