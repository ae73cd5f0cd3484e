# The types of afe._afe, the compiled extension (python/src/*.rs), checked against it by mypy.stubtest.

import os
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union, final

import numpy as np
import numpy.typing as npt

# a path as PathBuf takes it (os.fspath, then a str)
_Path = Union[str, os.PathLike[str]]
# an output as handed over: float64, complex128, float32 or complex64 (dtype="float32")
_Array = npt.NDArray[Any]
# a wire message's header: (seq, first_input_frame, input_frames, count, t_ns)
_Header = Tuple[int, int, int, int, int]

__all__ = [
    "Manager",
    "catalog",
    "host",
    "process",
    "process_file",
    "read_wav",
    "raa",
    "locate",
    "render",
    "transfer",
    "heads",
    "batch_run",
    "batch_plan",
    "batch_compute",
    "store_status",
    "store_read",
    "save_zarr",
    "load_zarr",
    "check_zarr",
    "wire_read_audio",
    "wire_read_frames",
    "__version__",
]

__version__: str

@final
class Manager:
    def __new__(
        cls,
        fs: float,
        channels: int,
        threads: int,
        keep_history: bool,
        history_seconds: Optional[float],
    ) -> Manager: ...
    @property
    def fs(self) -> float: ...
    @property
    def channels(self) -> int: ...
    @property
    def threads(self) -> int: ...
    def cancel(self) -> None: ...
    def set_head_yaw(self, t_s: float, yaw_deg: float) -> None: ...
    def add_request(self, name: str, params: Optional[Dict[str, Any]]) -> int: ...
    def remove_request(self, handle: int) -> None: ...
    def modify_parameter(self, handle: int, name: str, value: Any) -> None: ...
    def frames(self) -> Dict[str, Dict[str, Any]]: ...
    def request_outputs(self, handle: int) -> List[str]: ...
    def request_parameters(self, handle: int) -> Dict[str, Any]: ...
    def handles(self) -> List[int]: ...
    def process_chunk(self, x: npt.NDArray[np.float64]) -> Dict[str, _Array]: ...
    def process_signal(self, x: npt.NDArray[np.float64]) -> Dict[str, _Array]: ...
    def prepare(self, max_chunk: int) -> None: ...
    def reset(self) -> None: ...
    def outputs(self) -> Tuple[Dict[str, _Array], Dict[str, Dict[str, Any]]]: ...
    def describe(self) -> Dict[str, Dict[str, Any]]: ...
    def info(self) -> Dict[str, Dict[str, Any]]: ...

def catalog() -> List[Dict[str, Any]]: ...
def host() -> Dict[str, Any]: ...
def process(
    x: npt.NDArray[np.float64],
    fs: float,
    requests: Sequence[Tuple[str, Dict[str, Any]]],
    params: Optional[Dict[str, Any]],
    chunk: Optional[int],
    threads: int,
    all: bool,
    dtype: str,
) -> Tuple[Dict[str, _Array], Dict[str, Dict[str, Any]]]: ...
def process_file(
    path: _Path,
    fs: Optional[float],
    requests: Sequence[Tuple[str, Dict[str, Any]]],
    params: Optional[Dict[str, Any]],
    chunk: Optional[int],
    threads: int,
    all: bool,
    dtype: str,
) -> Tuple[Dict[str, _Array], Dict[str, Dict[str, Any]]]: ...
def read_wav(path: _Path) -> Tuple[npt.NDArray[np.float64], float]: ...
def raa(
    x: npt.NDArray[np.float64], fs: float, constants: Optional[Dict[str, Any]]
) -> Tuple[Dict[str, float], Dict[str, Union[npt.NDArray[np.float64], float, int]]]: ...
def locate(
    x: npt.NDArray[np.float64],
    fs: float,
    head: str,
    sources: Optional[int],
    head_yaw: Optional[npt.NDArray[np.float64]],
    track: bool,
) -> Dict[str, Any]: ...
def render(
    x: npt.NDArray[np.float64], fs: float, head: str, azimuth_deg: float
) -> npt.NDArray[np.float64]: ...
def transfer(
    freqs_hz: npt.NDArray[np.float64], head: str, azimuth_deg: float
) -> npt.NDArray[np.complex128]: ...
def heads() -> List[Tuple[str, str]]: ...
def batch_run(
    inputs: Sequence[_Path], store: _Path, spec: Dict[str, Any], options: Dict[str, Any]
) -> Dict[str, Any]: ...
def batch_plan(
    inputs: Sequence[_Path], store: _Path, spec: Dict[str, Any], options: Dict[str, Any]
) -> Tuple[List[Tuple[str, str, float]], int]: ...
def batch_compute(store: _Path, id: str, path: _Path, audio_s: float) -> Dict[str, Any]: ...
def store_status(store: _Path) -> Dict[str, Any]: ...
def store_read(store: _Path, id: str) -> Tuple[Dict[str, _Array], Dict[str, Dict[str, Any]]]: ...
def save_zarr(
    path: _Path,
    arrays: Sequence[Tuple[str, str, Sequence[int], Union[bytes, bytearray], Dict[str, Any]]],
) -> None: ...
def load_zarr(path: _Path) -> Tuple[Dict[str, _Array], Dict[str, Dict[str, Any]]]: ...
def check_zarr(path: _Path) -> Optional[str]: ...
def wire_read_audio(data: bytes) -> Tuple[_Header, npt.NDArray[np.float64]]: ...
def wire_read_frames(
    data: bytes,
) -> Tuple[_Header, List[Tuple[int, int, int, npt.NDArray[np.float64]]]]: ...
