"""Residue: denoise Monte Carlo renders with a direct residual network, and score the result.

Images are float32 NumPy arrays of height x width x channels."""
from typing import Callable, Optional

import numpy as np
import numpy.typing as npt

Image = npt.NDArray[np.float32]


class Error(Exception):
    """A residue error: its message names the file, the channel or the option and what was expected."""


class Cancelled(Exception):
    """A denoise stopped by its CancelToken or its progress callback."""


class CancelToken:
    def __init__(self) -> None: ...
    def cancel(self) -> None:
        """Asks the denoise to stop (within one network layer); safe from any thread."""
    @property
    def cancelled(self) -> bool: ...


class AovStack:
    """A render's AOVs as loaded and recognised."""
    @property
    def color(self) -> Image: ...
    @property
    def albedo(self) -> Optional[Image]: ...
    @property
    def normal(self) -> Optional[Image]: ...
    @property
    def depth(self) -> Optional[Image]: ...
    @property
    def variance(self) -> Optional[Image]: ...
    @property
    def reference(self) -> Optional[Image]: ...
    @property
    def motion(self) -> Optional[Image]: ...
    @property
    def convention(self) -> str: ...
    @property
    def notes(self) -> list[str]: ...
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...


def load(path: str, reference: Optional[str] = None) -> AovStack:
    """Loads a render: one multilayer EXR, or a folder of single-AOV files."""


def load_frames(pattern: str, frames: Optional[str] = None, reference: Optional[str] = None) -> list[AovStack]:
    """Frames of a shot by pattern (shot.####.exr): those of `frames` (1001-1100, 1,5,7-20:2), else every one
    that exists; `reference` a pattern of their references. A missing frame is an error naming its file."""


def stack(color: Image, albedo: Optional[Image] = None, normal: Optional[Image] = None, depth: Optional[Image] = None,
          reference: Optional[Image] = None, normal_space: str = "camera") -> AovStack:
    """A render from arrays by role (normals in camera space have +z towards the viewer)."""


Roi = tuple[int, int, int, int]  # x, y, width, height


def denoise(stack: AovStack, model: str = "multiscale", precision: str = "fp32", strength: float = 1.0,
            ensemble: int = 0, tile: int = 0, energy_correction: bool = True, roi: Optional[Roi] = None,
            progress: Optional[Callable[[int, int], bool]] = None,
            cancel: Optional[CancelToken] = None,
            on_tile: Optional[Callable[[Roi, Image], Optional[bool]]] = None) -> Image:
    """Denoises a loaded render with a model (as residue-cli's -m takes it); returns its colour, H x W x 3.

    on_tile((x, y, w, h), pixels): each tile of the result as the network left it (for a preview; the energy
    correction and the strength come later); returning False stops the run (residue.Cancelled)."""


def denoise_to_exr(stack: AovStack, path: str, model: str = "multiscale", precision: str = "fp32",
                   strength: float = 1.0, ensemble: int = 0, tile: int = 0, energy_correction: bool = True,
                   roi: Optional[Roi] = None, half: bool = True, overwrite: bool = False,
                   progress: Optional[Callable[[int, int], bool]] = None,
                   cancel: Optional[CancelToken] = None,
                   on_tile: Optional[Callable[[Roi, Image], Optional[bool]]] = None) -> dict:
    """denoise() written as residue-cli writes it, with residue:* provenance; returns what ran."""


def models() -> list[dict]:
    """The model cards: family, alias_of, method, architecture, ensemble, gflop_per_mp, variants, description,
    file, validation ({relmse, ssim, scenes} or None), fp32_s_per_mp, bf16_s_per_mp."""


def error_map(test: Image, reference: Image, kind: str = "rse", eps: float = 0.01) -> Image:
    """A per-pixel map, H x W x 1: abs, se, rse or ssim."""


def metrics(test: Image, reference: Image, eps: float = 0.01) -> dict[str, float]:
    """relMSE, MSE, PSNR, SSIM (and the pixel counts) of test against reference, as residue-cli eval."""


def flip(test: Image, reference: Image) -> dict:
    """HDR-FLIP: {"mean": float, "map": H x W x 1 array, "exposures": (start, stop, count)}."""


def denoise_frame(frames: list[AovStack], t: int, model: str = "multiscale-temporal", precision: str = "fp32",
                  strength: float = 1.0, ensemble: int = 0, tile: int = 0, energy_correction: bool = True,
                  roi: Optional[Roi] = None, progress: Optional[Callable[[int, int], bool]] = None,
                  cancel: Optional[CancelToken] = None,
                  on_tile: Optional[Callable[[Roi, Image], Optional[bool]]] = None) -> tuple[Image, list[int]]:
    """Frame t of a shot denoised as residue-cli denoise --temporal does (a temporal model reads its neighbours
    warped to it; frames beyond the list are missing). Returns (colour, the neighbour offsets that were missing)."""


def temporal_blend(frames: list[AovStack], denoised: list[Image], t: int, tolerance: float = 0.5) -> Image:
    """Frame t's denoised colour blended with frames t-1 and t+1's along the motion, as --temporal-blend does."""


def write_exr(path: str, image: Image, half: bool = True, overwrite: bool = False) -> None:
    """Writes an image as an EXR, atomically; an existing file is replaced only with overwrite=True."""
