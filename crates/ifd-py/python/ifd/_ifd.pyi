"""Type stubs of the compiled extension ``ifd._ifd`` (strict types; ``ifd`` converts)."""

from os import PathLike
from typing import Any, Literal, Optional, Union

import numpy as np
import numpy.typing as npt

__version__: str
__build_profile__: str  # 'dev' or 'release'

F32 = npt.NDArray[np.float32]
F64 = npt.NDArray[np.float64]
_Path = Union[str, PathLike[str]]

class Decomposition:
    """A planar filter as a sparse sum of displaced isotropic Gaussians."""

    @staticmethod
    def load(path: _Path) -> Decomposition: ...
    @staticmethod
    def from_json(text: str) -> Decomposition: ...
    @staticmethod
    def from_terms(terms: F64) -> Decomposition: ...
    def save(self, path: _Path) -> None: ...
    def to_json(self) -> str: ...
    @property
    def terms(self) -> F64: ...
    @property
    def spec(self) -> Optional[str]: ...
    @property
    def kernel_size(self) -> Optional[tuple[int, int]]: ...
    @property
    def sampling(self) -> str: ...
    @property
    def report(self) -> Optional[dict[str, Any]]: ...
    def halo(self, scale: float = 1.0) -> int: ...
    def __len__(self) -> int: ...
    def __eq__(self, other: object) -> bool: ...
    def __reduce__(self) -> tuple[Any, tuple[str]]: ...

class SphereDecomposition:
    """A spherical filter as rotated lobes."""

    @staticmethod
    def load(path: _Path) -> SphereDecomposition: ...
    @staticmethod
    def from_json(text: str) -> SphereDecomposition: ...
    def save(self, path: _Path) -> None: ...
    def to_json(self) -> str: ...
    @property
    def lmax(self) -> int: ...
    @property
    def profile(self) -> str: ...
    @property
    def directions(self) -> F64: ...
    @property
    def weights(self) -> F64: ...
    @property
    def condition_number(self) -> float: ...
    def __reduce__(self) -> tuple[Any, tuple[str]]: ...

def last_call_seconds() -> float: ...
def _decomposition_from_json(text: str) -> Decomposition: ...
def decompose_filter(
    spec: Optional[str] = None,
    kernel: Optional[F64] = None,
    *,
    tol: float = 0.01,
    max_terms: Optional[int] = None,
    levels: Optional[int] = None,
    alpha: Optional[float] = None,
    oversample: Optional[int] = None,
    min_sigma: Optional[float] = None,
    margin: Optional[int] = None,
) -> Decomposition: ...
def fit_cached(
    spec: Optional[str] = None,
    kernel: Optional[F64] = None,
    *,
    tol: float = 0.01,
) -> Decomposition: ...
def filter(
    image: F32,
    decomposition: Decomposition,
    *,
    angle: float = 0.0,
    angle_map: Optional[F32] = None,
    scale: float = 1.0,
    scale_map: Optional[F32] = None,
    border: str = "reflect101",
    interp: str = "auto",
    eval_budget: Optional[float] = None,
    scale_range: Optional[tuple[float, float]] = None,
) -> F32: ...
def filter_sigma_map(image: F32, sigma_map: F32, *, border: str = "reflect101") -> F32: ...
def filter_set(
    image: F32,
    decompositions: list[Decomposition],
    filter_map: F32,
    *,
    angle: float = 0.0,
    angle_map: Optional[F32] = None,
    scale: float = 1.0,
    scale_map: Optional[F32] = None,
    border: str = "reflect101",
    interp: str = "auto",
    eval_budget: Optional[float] = None,
) -> F32: ...
def filter_alignment(
    decomposition: Decomposition,
    shape: tuple[int, int, int],
    scale_range: tuple[float, float],
    angle_varies: bool,
    *,
    border: str = "reflect101",
    interp: str = "auto",
    eval_budget: Optional[float] = None,
) -> int: ...
def hessian(image: F32, sigma: float, *, border: str = "reflect101") -> F32: ...
def smooth(
    image: F32,
    sigma: float,
    *,
    max_aspect: float = 8.0,
    gamma: float = 1.0,
    epsilon: float = 0.02,
    hessian_sigma: Optional[float] = None,
    strength: float = 1.0,
    mode: str = "per-pixel",
    border: str = "reflect101",
) -> F32: ...
def compare(
    a: F32, b: F32, *, data_range: Optional[float] = None, crop_border: int = 0
) -> dict[str, Any]: ...
def sphere_sh(
    env: F32, lmax: int, *, keep_negatives: bool = False, projection: Optional[Literal["texel", "centre"]] = None
) -> F64: ...
def sphere_synthesize(coeffs: F64, width: int, height: int) -> F32: ...
def sphere_rotate(
    coeffs: F64, zyz: tuple[float, float, float], *, method: str = "zhf"
) -> F64: ...
def sphere_decompose(
    kernel: Union[str, F64],
    lmax: int,
    *,
    directions: str = "fibonacci",
    profile: str = "zonal",
    seed: int = 1,
    max_cond: float = 1e10,
) -> SphereDecomposition: ...
def sphere_filter(
    env: F32,
    decomposition: SphereDecomposition,
    *,
    size: Optional[tuple[int, int]] = None,
    raw: bool = False,
    keep_negatives: bool = False,
    projection: Optional[Literal["texel", "centre"]] = None,
) -> F32: ...
def sphere_shade(
    coeffs: F64,
    brdf: str,
    normals: F64,
    views: F64,
    *,
    lmax: Optional[int] = None,
    table: Optional[_Path] = None,
    tangents: Optional[F64] = None,
) -> F64: ...
