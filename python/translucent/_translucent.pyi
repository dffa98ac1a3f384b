"""Type stubs of the Rust core (``translucent._translucent``); the package re-exports these."""

import os
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

_Path = Union[str, "os.PathLike[str]"]
_Rgb = Union[float, Sequence[float]]

__version__: str

class Error(Exception):
    """An error of translucent: a render, a recovery or a file that failed."""

class Medium:
    """A homogeneous medium inside its boundary (σ_t per channel in 1/scene unit, albedo
    σ_s/σ_t per channel, Henyey–Greenstein g, relative index of refraction eta, the boundary's
    GGX roughness). g is one number, or three (R, G, B) for a medium whose forward scattering
    depends on the wavelength. Out-of-range values raise ValueError naming the field and the fix."""

    def __init__(
        self, sigma_t: _Rgb, albedo: _Rgb, g: _Rgb = 0.0, eta: float = 1.0, roughness: float = 0.0
    ) -> None: ...
    @property
    def sigma_t(self) -> Tuple[float, float, float]: ...
    @property
    def albedo(self) -> Tuple[float, float, float]: ...
    @property
    def g(self) -> Union[float, Tuple[float, float, float]]: ...
    @property
    def eta(self) -> float: ...
    @property
    def roughness(self) -> float: ...
    def replace(
        self,
        *,
        sigma_t: Optional[_Rgb] = None,
        albedo: Optional[_Rgb] = None,
        g: Optional[_Rgb] = None,
        eta: Optional[float] = None,
        roughness: Optional[float] = None,
    ) -> "Medium": ...
    @staticmethod
    def measured(
        name: str, unit: str = "mm", g: _Rgb = 0.0, eta: float = 1.0, roughness: float = 0.0
    ) -> "Medium": ...
    def to_dict(self) -> Dict[str, Any]: ...

class Dataset:
    """Views (camera, light, image), the object's mesh, what the capture states about the
    object, and (synthetic) its truth."""

    @staticmethod
    def load(path: _Path) -> "Dataset": ...
    @staticmethod
    def from_scene(path: _Path) -> "Dataset": ...
    @staticmethod
    def _from_arrays(
        vertices: npt.NDArray[np.float32],
        faces: npt.NDArray[np.uint32],
        to_world: npt.NDArray[np.float32],
        intrinsics: npt.NDArray[np.float32],
        resolution: npt.NDArray[np.uint32],
        light_positions: npt.NDArray[np.float32],
        light_intensities: npt.NDArray[np.float32],
        images: Optional[Sequence[npt.NDArray[np.float32]]],
        eta: float,
        roughness: float,
        g: _Rgb,
        truth: Optional[Medium],
        length_unit: Optional[str],
    ) -> "Dataset": ...
    def save(self, path: _Path, overwrite: bool = False) -> "Dataset": ...
    def with_images(self, images: Sequence[npt.NDArray[np.float32]]) -> "Dataset": ...
    def __len__(self) -> int: ...
    @property
    def path(self) -> Optional[str]: ...
    @property
    def to_world(self) -> npt.NDArray[np.float32]: ...
    @property
    def intrinsics(self) -> npt.NDArray[np.float32]: ...
    @property
    def resolution(self) -> npt.NDArray[np.uint32]: ...
    @property
    def light_positions(self) -> npt.NDArray[np.float32]: ...
    @property
    def light_intensities(self) -> npt.NDArray[np.float32]: ...
    @property
    def images(self) -> List[Optional[npt.NDArray[np.float32]]]: ...
    @property
    def mesh(self) -> Tuple[npt.NDArray[np.float32], npt.NDArray[np.uint32]]: ...
    @property
    def object(self) -> Optional[Dict[str, float]]: ...
    @property
    def truth(self) -> Optional[Medium]: ...
    @property
    def length_unit(self) -> Optional[str]: ...
    @property
    def warnings(self) -> List[str]: ...

def render(
    source: Union[Dataset, str],
    medium: Optional[Medium] = None,
    *,
    model: str = "volpath",
    spp: Optional[int] = None,
    seed: Optional[int] = None,
    derivatives: bool = False,
    max_depth: Optional[int] = None,
    threads: Optional[int] = None,
    model_file: Optional[str] = None,
) -> Dict[str, Any]: ...
def optimize(
    dataset: str,
    out: str,
    options: Optional[Dict[str, Any]] = None,
    callback: Optional[Callable[[int, Dict[str, Any], float], Optional[bool]]] = None,
    verbose: bool = True,
    threads: Optional[int] = None,
) -> None: ...
def default_options() -> Dict[str, Tuple[Any, str]]: ...
def read_image(path: _Path) -> npt.NDArray[np.float32]: ...
def write_image(
    path: _Path, image: npt.NDArray[np.float32], exposure: float = 1.0, overwrite: bool = False
) -> None: ...
def import_colmap(
    model: _Path,
    images: _Path,
    mesh: _Path,
    *,
    flash: Optional[Sequence[float]] = None,
    light_positions: Optional[_Path] = None,
    intensity: _Rgb = 1.0,
    masks: Optional[_Path] = None,
    transfer: Optional[str] = None,
    exposure: float = 1.0,
    eta: Optional[float] = None,
    roughness: Optional[float] = None,
    g: Optional[_Rgb] = None,
    units: Optional[str] = None,
) -> Dataset: ...
def import_nerf(
    transforms: _Path,
    mesh: _Path,
    *,
    images: Optional[_Path] = None,
    flash: Optional[Sequence[float]] = None,
    light_positions: Optional[_Path] = None,
    intensity: _Rgb = 1.0,
    masks: Optional[_Path] = None,
    transfer: Optional[str] = None,
    exposure: float = 1.0,
    eta: Optional[float] = None,
    roughness: Optional[float] = None,
    g: Optional[_Rgb] = None,
    units: Optional[str] = None,
) -> Dataset: ...
