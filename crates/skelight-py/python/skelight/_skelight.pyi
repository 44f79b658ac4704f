"""Type stubs of the compiled module (see the docstrings in crates/skelight-py/src)."""

from os import PathLike
from pathlib import Path
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

class SkelightError(RuntimeError): ...
class LoadError(SkelightError): ...

class Scene:
    path: Optional[Path]
    width: int
    height: int
    triangles: int
    lights: int
    warnings: List[str]
    spp: int
    max_depth: int
    camera: Dict[str, Any]
    def set_resolution(self, width: int, height: int) -> None: ...
    def info(self) -> Dict[str, Any]: ...
    def skeleton(self, resolution: int = 128) -> Dict[str, Any]: ...

class Render:
    image: npt.NDArray[np.float32]
    variance: npt.NDArray[np.float32]
    spp: int
    samples: Tuple[int, int]
    shard: Optional[Tuple[int, int]]
    key: str
    seconds: float
    preparation_seconds: float
    def __array__(self, dtype: Any = None, copy: Optional[bool] = None) -> npt.NDArray[Any]: ...
    def save(self, path: Union[str, PathLike[str]], exposure: float = 0.0) -> None: ...
    def to_bytes(self) -> bytes: ...
    @staticmethod
    def from_bytes(data: bytes) -> "Render": ...
    @staticmethod
    def load(path: Union[str, PathLike[str]]) -> "Render": ...

def load_file(path: Union[str, PathLike[str]], **defines: Any) -> Scene: ...
def default_scene() -> Scene: ...
def render(
    scene: Scene,
    integrator: str = "pt",
    spp: Optional[int] = None,
    time: Optional[float] = None,
    seed: int = 0,
    params: Optional[Dict[str, Any]] = None,
    shard: Optional[Tuple[int, int]] = None,
    threads: int = 0,
    progress: Optional[Callable[[Dict[str, Any]], None]] = None,
    device: str = "cpu",
    debug: Optional[Union[str, PathLike[str]]] = None,
) -> Render: ...
def render_key(
    scene: Scene,
    integrator: str = "pt",
    spp: Optional[int] = None,
    seed: int = 0,
    params: Optional[Dict[str, Any]] = None,
    shard: Optional[Tuple[int, int]] = None,
    device: str = "cpu",
) -> str: ...
def merge(parts: Sequence[Union[Render, str, PathLike[str]]]) -> Render: ...
def load_image(path: Union[str, PathLike[str]]) -> npt.NDArray[np.float32]: ...
def integrators() -> Dict[str, Dict[str, Any]]: ...
def compare(
    scene: Scene,
    reference: Union[str, PathLike[str], npt.NDArray[np.float32]],
    integrators: List[str],
    time: float,
    every: float = 0.0,
    seed: int = 0,
    threads: int = 0,
) -> Dict[str, Dict[str, Any]]: ...
