"""Type stubs of the native module `samara._samara` (PyO3). Use the wrappers in
`samara` (numpy in and out, frozen result classes); this layer takes float64
row-major bytes and returns bytes, or the serde fields of the library's typed results
as dicts, lists and numbers (no JSON text; non-finite floats kept), from which
`samara` builds its result classes. `test_stubs_match_the_native_module` checks every
name and every signature here against the module."""

from typing import Any, Dict, List, Optional, Tuple

__version__: str

class SamaraError(Exception):
    """A computation of samara failed (bad arguments raise ValueError)."""

class Network:
    @staticmethod
    def from_onnx_bytes(data: bytes, name: str) -> "Network": ...
    def to_onnx(self, with_normalisation: bool = True, float64: bool = False) -> bytes: ...
    @property
    def n_inputs(self) -> int: ...
    @property
    def n_outputs(self) -> int: ...
    @property
    def input_names(self) -> List[str]: ...
    @property
    def output_names(self) -> List[str]: ...
    def eval_rows(self, xs: bytes, n: int) -> bytes: ...

class Spec:
    def __init__(self, text: str, file: str, dir: str) -> None: ...
    @property
    def properties(self) -> List[str]: ...
    @property
    def networks(self) -> List[Tuple[str, List[str], List[str]]]: ...
    @property
    def params(self) -> Dict[str, Optional[Tuple[float, float]]]: ...
    @property
    def file(self) -> str: ...
    def verify(
        self,
        networks: Dict[str, Network],
        params: Dict[str, float],
        datasets: Dict[str, str],
        property: Optional[str],
        timeout: float,
        max_nodes: int,
    ) -> Tuple[List[Dict[str, Any]], List[str]]: ...
    def critical(
        self,
        property: str,
        param: str,
        networks: Dict[str, Network],
        params: Dict[str, float],
        datasets: Dict[str, str],
        timeout: float,
        max_nodes: int,
    ) -> Tuple[Dict[str, Any], List[str]]: ...

def robustness(
    network: Network,
    rows: bytes,
    n: int,
    cols: int,
    eps: List[float],
    lipschitz: List[float],
    reference: str,
    form: str,
    timeout: float,
    max_nodes: int,
) -> Dict[str, Any]: ...
def read_table(path: str) -> Tuple[bytes, int, int]: ...
def simulate(
    model: str,
    controller: str,
    ex: float,
    network: Optional[Network],
    clip: bool,
    y0: Optional[List[float]],
    integrator: str,
    horizon: float,
    period: float,
) -> List[Tuple[bytes, int, List[float], int]]: ...
def reach(
    network: Network,
    model: str,
    init: Dict[str, Tuple[float, float]],
    horizon: float,
    period: float,
    goal_ystar: Optional[float],
    goal_from: Optional[float],
    clip: bool,
    max_leaves: Optional[int],
    samples: Optional[int],
    seed: Optional[int],
    network_name: str,
    threads: Optional[int],
) -> Dict[str, Any]: ...
def reach_system(
    system: str,
    file: str,
    network: Network,
    grid: Dict[str, int],
    cells: Optional[Tuple[int, int]],
    order: int,
    network_error: str,
    lifted_weight: int,
    lift_at: float,
    max_leaves: int,
    samples: int,
    seed: int,
    timeout: Optional[float],
    time_order: Optional[int] = None,
    step_tol: Optional[float] = None,
) -> Dict[str, Any]: ...
def merge_reach_system(parts: List[Dict[str, Any]]) -> Dict[str, Any]: ...
def reach_adaptive_shard(
    system: str,
    file: str,
    network: Network,
    grid: Dict[str, int],
    shard: Tuple[int, int],
    target_ratio: float,
    order: int,
    network_error: str,
    lifted_weight: int,
    lift_at: float,
    max_leaves: int,
    samples: int,
    seed: int,
    timeout: Optional[float],
    checkpoint: Optional[str],
    time_order: Optional[int] = None,
    step_tol: Optional[float] = None,
) -> str: ...
def merge_adaptive_shards(docs: List[str]) -> str: ...
def train(
    rows: bytes,
    n: int,
    cols: int,
    normalisation: Optional[Tuple[List[float], List[float]]],
    method: str,
    attack: str,
    arch: List[int],
    epochs: int,
    batch: int,
    lr: float,
    seed: int,
    eps: float,
    lipschitz: float,
    weight: Optional[float],
    ystar: float,
    max_restarts: Optional[int],
    min_r2: Optional[float],
) -> Tuple[Network, Dict[str, Any]]: ...
