"""translucent: measure what a translucent object is made of from images of it.

Given the object's mesh, the cameras, a point light per image and the images, translucent
recovers the extinction σ_t and the single-scattering albedo α of a homogeneous medium per RGB
channel, with 95 % intervals, by differentiable rendering (a learned shape-adaptive BSSRDF,
refined by a differentiable volumetric path tracer). This package is the library the
``translucent`` command line runs, with NumPy arrays in and out:

>>> import translucent as tl
>>> ds = tl.Dataset.load("out/demo/dataset")              # any dataset folder the CLI reads
>>> r = tl.render(ds, tl.Medium(sigma_t=30, albedo=0.9), spp=16, seed=0)
>>> r.images[0].shape                                     # (H, W, 3) float32, linear RGB
>>> result = tl.optimize(ds, "out/fit", iterations=300)   # the CLI's defaults otherwise
>>> print(result)                                         # estimate, 95 % intervals, status

Units and conventions are the datasets' (DATASET.md): lengths in scene units, σ_t in 1/unit,
light intensity in W/sr per channel, cameras as Mitsuba 3's ``to_world`` (columns x = image
left, y = image up, z = view direction, position).
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Dict, List, Optional, Sequence, Union

import numpy as np

from . import _translucent
from ._translucent import (
    Dataset,
    Error,
    Medium,
    __version__,
    import_colmap,
    import_nerf,
    read_image,
    write_image,
)
from . import mitsuba

__all__ = [
    "Dataset",
    "Error",
    "Medium",
    "Rendering",
    "Result",
    "default_options",
    "import_colmap",
    "import_nerf",
    "make_dataset",
    "mitsuba",
    "optimize",
    "read_image",
    "render",
    "write_image",
    "__version__",
]

PathLike = Union[str, "os.PathLike[str]"]


def _array(x: Any, name: str, shape: Sequence[Optional[int]], kind: str) -> np.ndarray:
    """``x`` as a C-contiguous array of the given trailing shape (None: any length), converted
    to float32 (``kind`` "f") or uint32 (``kind`` "u"); a ValueError naming ``name`` otherwise."""
    a = np.asarray(x)
    want = "(" + ", ".join("N" if s is None else str(s) for s in shape) + ")"
    if a.ndim != len(shape) or any(s is not None and a.shape[i] != s for i, s in enumerate(shape)):
        raise ValueError(f"{name}: expected an array of shape {want}, got shape {a.shape}")
    if kind == "f":
        if a.dtype.kind not in "fiu":
            raise ValueError(f"{name}: expected numbers, got an array of dtype {a.dtype}")
        out = np.ascontiguousarray(a, dtype=np.float32)
        if not np.all(np.isfinite(out)):
            raise ValueError(f"{name}: every value must be finite")
        return out
    if a.dtype.kind not in "iu":
        raise ValueError(f"{name}: expected integers, got an array of dtype {a.dtype}")
    if a.size and (a.min() < 0 or a.max() > np.iinfo(np.uint32).max):
        raise ValueError(f"{name}: indices must lie in [0, 2^32)")
    return np.ascontiguousarray(a, dtype=np.uint32)


def make_dataset(
    vertices: Any,
    faces: Any,
    *,
    to_world: Any,
    resolution: Any,
    light_positions: Any,
    light_intensities: Any,
    fov_x: Any = None,
    intrinsics: Any = None,
    images: Optional[Sequence[np.ndarray]] = None,
    eta: float = 1.0,
    roughness: float = 0.0,
    g: Union[float, Sequence[float]] = 0.0,
    truth: Optional[Medium] = None,
    length_unit: Optional[str] = None,
) -> Dataset:
    """A dataset from arrays: the object's mesh, one camera and point light per view, and
    optionally the images (``Dataset.save`` writes it as a dataset.json folder).

    vertices: (V, 3) positions in scene units; faces: (F, 3) vertex indices (outward winding;
        an inside-out closed mesh is flipped, as when a mesh file is read).
    to_world: (N, 4, 4) camera-to-world matrices, Mitsuba 3's convention: columns x (image
        left), y (image up), z (view direction), position.
    resolution: (N, 2) film width and height in pixels (or one (2,) pair for every view).
    fov_x: horizontal field of view in degrees, per view (N,) or one value; or
    intrinsics: (N, 4) f_x, f_y, c_x, c_y in pixels (row 0 at the top), for calibrated cameras.
    light_positions: (N, 3) point light positions; light_intensities: (N, 3) radiant intensity
        in W/sr per channel (or one (3,) value for every view).
    images: N arrays (H, W, 3) float32 of linear radiance, or None (render them later and give
        them with ``Dataset.with_images``).
    eta, roughness, g: what is known about the object: the boundary's relative index of
        refraction (1: index-matched), its GGX roughness (0: smooth) and the phase function's g
        (one value, or three: R, G, B).
    truth: the medium a synthetic dataset was made with (a report only).
    length_unit: "mm", "cm" or "m" when the scene's unit is a real length.
    """
    tw = _array(to_world, "to_world", (None, 4, 4), "f")
    n = tw.shape[0]
    if n == 0:
        raise ValueError("to_world: a dataset needs at least one view")

    def per_view(x: Any, name: str, width: int, kind: str) -> np.ndarray:
        a = np.asarray(x)
        if a.ndim == 1:
            a = np.broadcast_to(a, (n, a.shape[0]))
        a = _array(a, name, (n, width), kind)
        return a

    res = per_view(resolution, "resolution", 2, "u")
    if np.any(res == 0):
        raise ValueError("resolution: width and height must be at least 1 pixel")
    if (fov_x is None) == (intrinsics is None):
        raise ValueError("give the cameras' fov_x (degrees) or their intrinsics (f_x, f_y, c_x, c_y), one of the two")
    if intrinsics is not None:
        k = per_view(intrinsics, "intrinsics", 4, "f")
    else:
        fov = np.broadcast_to(np.asarray(fov_x, dtype=np.float64), (n,))
        if np.any(~np.isfinite(fov)) or np.any(fov <= 0) or np.any(fov >= 180):
            raise ValueError(f"fov_x: degrees in (0, 180), got {fov_x}")
        fx = 0.5 * res[:, 0] / np.tan(np.radians(fov) / 2)
        k = np.ascontiguousarray(
            np.stack([fx, fx, 0.5 * res[:, 0], 0.5 * res[:, 1]], axis=1), dtype=np.float32
        )
    lp = per_view(light_positions, "light_positions", 3, "f")
    li = per_view(light_intensities, "light_intensities", 3, "f")
    if np.any(li < 0):
        raise ValueError("light_intensities: radiant intensities must be ≥ 0 (W/sr)")
    if images is not None:
        images = list(images)
        if len(images) != n:
            raise ValueError(f"images: {len(images)} arrays for {n} views; give one per view")
    v = _array(vertices, "vertices", (None, 3), "f")
    f = _array(faces, "faces", (None, 3), "u")
    if f.size and f.max() >= len(v):
        raise ValueError(f"faces: index {int(f.max())} but only {len(v)} vertices")
    return Dataset._from_arrays(
        v, f, tw, k, res, lp, li, images, eta, roughness, g, truth, length_unit
    )


@dataclass
class Rendering:
    """What ``render`` returns: per view, the image and (with derivatives=True) its derivative
    images ∂I_c/∂σ_t,c and ∂I_c/∂α_c (and ∂I_c/∂g from the volumetric path tracer), each an
    (H, W, 3) float32 array."""

    images: List[np.ndarray]
    d_sigma_t: Optional[List[np.ndarray]]
    d_albedo: Optional[List[np.ndarray]]
    d_g: Optional[List[Optional[np.ndarray]]]
    seconds_per_view: List[float]
    model: str
    spp: int
    seed: int


def render(
    source: Union[Dataset, PathLike],
    medium: Optional[Medium] = None,
    *,
    model: str = "volpath",
    spp: Optional[int] = None,
    seed: Optional[int] = None,
    derivatives: bool = False,
    max_depth: Optional[int] = None,
    threads: Optional[int] = None,
    model_file: Optional[PathLike] = None,
) -> Rendering:
    """Renders every view of ``source`` (a Dataset, or the path of a scene file or dataset
    folder) at ``medium`` (default: the scene's medium or the dataset's truth), as
    ``translucent render`` does: the same seed and threads give the CLI's images bit for bit.

    model: "volpath" (the volumetric path tracer, default), "learned" (the learned BSSRDF;
        ``model_file`` for other weights) or "dipole".
    spp: samples per pixel (default: the scene's, else 64); seed: default the scene's, else 0;
    max_depth: the tracer's maximum depth (default: the scene's, else 32);
    threads: worker threads (None: all cores).
    derivatives: also the derivative images with respect to σ_t and α (and g, tracer).
    """
    r = _translucent.render(
        source if isinstance(source, Dataset) else os.fspath(source),
        medium,
        model=model,
        spp=spp,
        seed=seed,
        derivatives=derivatives,
        max_depth=max_depth,
        threads=threads,
        model_file=None if model_file is None else os.fspath(model_file),
    )
    return Rendering(**r)


@dataclass
class Result:
    """A recovery's outcome, as ``result.json`` records it (``to_dict()`` gives that dict).

    status: "ok", "failed" (the run or its checks say the estimate is wrong) or "interrupted"
        (stopped before its last iteration; ``optimize(..., resume=True)`` continues it).
    estimate: {"sigma_t": (R, G, B), "albedo": (R, G, B)}, with "g" and "light_scale" where
        recovered. interval95: the 95 % intervals of each, per channel, as (low, high);
    determined: per parameter and channel, whether the images determine it (an interval
        narrower than ±10 %); consistency: the tracer's check of the estimate.
    """

    status: str
    estimate: Dict[str, Any]
    interval95: Optional[Dict[str, Any]]
    determined: Optional[Dict[str, Any]]
    consistency: Optional[Dict[str, Any]]
    iterations: int
    out: Path
    raw: Dict[str, Any] = field(repr=False)

    @classmethod
    def read(cls, out: PathLike) -> "Result":
        """The result of the run in the output folder ``out``."""
        out = Path(out)
        with open(out / "result.json", encoding="utf-8") as f:
            raw = json.load(f)
        est = raw.get("estimate", {})
        iters = raw.get("iterations")
        return cls(
            status=raw.get("status", "incomplete"),
            estimate={k: tuple(v) if isinstance(v, list) else v for k, v in est.items() if v is not None},
            interval95=raw.get("interval95"),
            determined=raw.get("determined"),
            consistency=raw.get("consistency"),
            iterations=len(iters) if isinstance(iters, list) else int(iters or 0),
            out=out,
            raw=raw,
        )

    def to_dict(self) -> Dict[str, Any]:
        """result.json as a dict."""
        return self.raw

    def __str__(self) -> str:
        lines = [f"status {self.status} after {self.iterations} iterations ({self.out})"]
        for name in ("sigma_t", "albedo", "g", "light_scale"):
            if name not in self.estimate:
                continue
            v = self.estimate[name]
            iv = (self.interval95 or {}).get(name)
            det = (self.determined or {}).get(name)
            values = list(v) if isinstance(v, (list, tuple)) else [v]
            ivs = iv if isinstance(iv, list) and iv and isinstance(iv[0], list) else [iv]
            dets = det if isinstance(det, list) else [det]
            parts = []

            def f(x: Any) -> str:
                return "unbounded" if x is None else f"{x:.4g}"

            for c, x in enumerate(values):
                i = ivs[c] if c < len(ivs) else None
                d = dets[c] if c < len(dets) else None
                if not isinstance(i, list) or len(i) != 2:
                    parts.append(f(x))
                elif d is False:
                    parts.append(f"{f(x)} [not determined: {f(i[0])} to {f(i[1])} fit these images]")
                else:
                    parts.append(f"{f(x)} [{f(i[0])}, {f(i[1])}]")
            lines.append(f"  {name} = " + ", ".join(parts))
        return "\n".join(lines)


def default_options() -> Dict[str, Any]:
    """Every keyword ``optimize`` takes with its default (the CLI's ``optimize`` defaults, from
    the same library definition) and what it sets: {name: (default, description)}."""
    return _translucent.default_options()


def optimize(
    dataset: Union[Dataset, PathLike],
    out: PathLike = "out/optimize",
    *,
    callback: Optional[Callable[[int, Dict[str, Any], float], Optional[bool]]] = None,
    verbose: bool = True,
    threads: Optional[int] = None,
    **options: Any,
) -> Result:
    """Recovers σ_t and α (and g or the light scale where freed) from the dataset's images into
    the output folder ``out``, as ``translucent optimize --dataset D --out OUT`` does: the same
    defaults (``default_options()``), the same files (result.json, iterations.csv,
    convergence.png, final/, mitsuba/), and with the same seed and threads the same numbers.

    dataset: a Dataset or a dataset folder; a dataset made from arrays is first saved as
        ``OUT/dataset``.
    callback: called after every iteration as ``callback(iteration, parameters, loss)``; return
        False to stop the run cleanly (checkpointed; the result's status is "interrupted").
        Ctrl-C stops it the same way, then raises KeyboardInterrupt.
    verbose: print the run's report lines and show progress bars (on stderr).
    threads: worker threads (None: all cores).
    options: the CLI's options by their keyword names, e.g. iterations=300, spp=32, seed=0,
        model="volpath", free=["g"], overwrite=True; ``default_options()`` lists them all.
    """
    if isinstance(dataset, Dataset):
        if dataset.path is None:
            dataset = dataset.save(Path(out) / "dataset", overwrite=bool(options.get("overwrite")))
        path = dataset.path
    else:
        path = Path(dataset)
    _translucent.optimize(
        os.fspath(path), os.fspath(out), options, callback=callback, verbose=verbose, threads=threads
    )
    return Result.read(out)
