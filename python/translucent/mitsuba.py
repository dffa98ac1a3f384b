"""A recovered medium in Mitsuba 3's scene-dict form (``mi.load_dict``), and Mitsuba 3 scenes in.

The dicts follow what ``translucent optimize`` writes to ``OUT/mitsuba/medium.xml``: the boundary
is a ``null``, ``dielectric`` or GGX ``roughdielectric`` BSDF (η as ``int_ior`` with ``ext_ior``
1), the interior a ``homogeneous`` medium whose RGB σ_t is stored as σ_t/s with ``scale``
s = max σ_t (Mitsuba reads an RGB σ_t through its colour pipeline, which keeps values in
[0, 1] exact), the albedo as RGB and an ``hg`` phase function.

Mitsuba 3 scenes come in through the library's own reader (no Mitsuba installation needed):
``load_scene`` reads a scene .xml (shape from PLY/OBJ with ``to_world``, a homogeneous
``interior`` inside a null/dielectric/roughdielectric BSDF, point emitters, perspective
sensors) as a Dataset without images; a folder with ``scene.xml`` and an image per sensor is a
dataset (``Dataset.load``).
"""

from __future__ import annotations

import os
from typing import Any, Dict, Union

from ._translucent import Dataset, Medium

__all__ = ["bsdf_dict", "medium_dict", "shape_dict", "load_scene"]


def bsdf_dict(medium: Medium) -> Dict[str, Any]:
    """The boundary of ``medium`` as a Mitsuba 3 BSDF dict."""
    if medium.eta == 1.0:
        return {"type": "null"}
    if medium.roughness == 0.0:
        return {"type": "dielectric", "int_ior": float(medium.eta), "ext_ior": 1.0}
    return {
        "type": "roughdielectric",
        "distribution": "ggx",
        "alpha": float(medium.roughness),
        "int_ior": float(medium.eta),
        "ext_ior": 1.0,
    }


def medium_dict(medium: Medium) -> Dict[str, Any]:
    """The interior of ``medium`` as a Mitsuba 3 ``homogeneous`` medium dict (in the scene's
    length unit: Mitsuba's σ_t is per scene unit, as ours). Mitsuba 3's ``hg`` has one g for
    every channel: a medium with a g per channel raises ValueError (render each channel's g as a
    scene of its own)."""
    if not isinstance(medium.g, (int, float)):
        raise ValueError(
            f"the medium's g is per channel {medium.g}; Mitsuba 3's hg phase function has one g "
            "for every channel: render each channel's g as a scene of its own"
        )
    scale = max(medium.sigma_t)
    return {
        "type": "homogeneous",
        "sigma_t": {"type": "rgb", "value": [float(s / scale) for s in medium.sigma_t]},
        "scale": float(scale),
        "albedo": {"type": "rgb", "value": [float(a) for a in medium.albedo]},
        "phase": {"type": "hg", "g": float(medium.g)},
    }


def shape_dict(medium: Medium, filename: Union[str, "os.PathLike[str]"]) -> Dict[str, Any]:
    """A mesh file (``.ply`` or ``.obj``) made of ``medium``: the shape dict with its boundary
    BSDF and ``interior`` medium, ready for ``mi.load_dict({"type": "scene", "object": ...})``."""
    name = os.fspath(filename)
    ext = os.path.splitext(name)[1].lower().lstrip(".")
    if ext not in ("ply", "obj"):
        raise ValueError(f"{name}: a Mitsuba 3 mesh shape is a .ply or .obj file")
    return {
        "type": ext,
        "filename": name,
        "bsdf": bsdf_dict(medium),
        "interior": medium_dict(medium),
    }


def load_scene(path: Union[str, "os.PathLike[str]"]) -> Dataset:
    """A Mitsuba 3 scene .xml (``default`` parameters and ``$name`` substitution included) as a
    Dataset without images: its sensors, point emitters, mesh and medium (the truth, and what
    it states about the object)."""
    return Dataset.from_scene(os.fspath(path))
