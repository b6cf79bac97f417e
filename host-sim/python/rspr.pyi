"""Type stubs of the `rspr` module (host-sim/python/src/bindings.rs)."""

from os import PathLike
from typing import Iterable, Literal, Optional, Sequence, TypedDict, Union, overload

Numbers = Iterable[float]
"""Six numbers: a list, a tuple or a 1-D NumPy array."""
Rows = Iterable[Iterable[float]]
"""Many rows of six numbers: an N x 6 NumPy array or a list of rows."""
Errors = Literal["raise", "none"]

class RsprError(ValueError): ...
class InputError(RsprError): ...
class GeometryError(RsprError): ...
class IkError(RsprError): ...
class FkError(RsprError): ...
class JacobianError(RsprError): ...
class ForcesError(RsprError): ...
class SingularityError(RsprError): ...

class Fk(TypedDict):
    pose: list[float]
    iterations: int

class Jacobian(TypedDict):
    j: list[list[float]]
    jtilde: list[list[float]]
    inv_cond: float

class Circuit(TypedDict):
    variety: str
    lines: list[int]

class Residual(TypedDict):
    configuration: str
    residual: float
    which: str
    holds: bool

class Gained(TypedDict):
    twist_scaled: list[float]
    pitch_mm: Optional[float]
    axis_mm: Optional[list[float]]

class Singularity(TypedDict, total=False):
    serial_mm: list[float]  # RSPR
    serial_mm2: list[float]  # USR
    serial_frac: list[float]
    parallel_inv_cond: float
    det_sign: int
    nearest: str
    rank: int
    relative_sigma: list[float]
    circuits: list[Circuit]
    configurations: list[str]
    residuals: list[Residual]
    complex: Optional[str]
    gained: list[Gained]
    serial_cases: list[str]

class Robot:
    def __init__(self, kind: Literal["rspr", "usr"] = "rspr") -> None: ...
    @staticmethod
    def from_file(path: Union[str, PathLike[str]]) -> Robot: ...
    @property
    def kind(self) -> str: ...
    @property
    def source(self) -> str: ...
    @property
    def joint_names(self) -> list[str]: ...
    @property
    def rp_mm(self) -> float: ...
    @property
    def hc_mm(self) -> float: ...
    @overload
    def ik(self, pose: Numbers, branch: int = 0, errors: Errors = "raise") -> list[float]: ...
    @overload
    def ik(self, pose: Rows, branch: int = 0, errors: Errors = "raise") -> list[Optional[list[float]]]: ...
    def ik_branches(self, pose: Numbers) -> dict[int, list[float]]: ...
    def fk(self, joints: Numbers, branch: int = 0, initial: Optional[Numbers] = None) -> Fk: ...
    @overload
    def jacobian(self, pose: Numbers, branch: int = 0, errors: Errors = "raise") -> Jacobian: ...
    @overload
    def jacobian(self, pose: Rows, branch: int = 0, errors: Errors = "raise") -> list[Optional[Jacobian]]: ...
    @overload
    def forces(self, pose: Numbers, wrench: Numbers, branch: int = 0, min_inv_cond: float = 1e-6, errors: Errors = "raise") -> list[float]: ...
    @overload
    def forces(self, pose: Rows, wrench: Numbers, branch: int = 0, min_inv_cond: float = 1e-6, errors: Errors = "raise") -> list[Optional[list[float]]]: ...
    @overload
    def singularity(self, pose: Numbers, branch: int = 0, errors: Errors = "raise") -> Singularity: ...
    @overload
    def singularity(self, pose: Rows, branch: int = 0, errors: Errors = "raise") -> list[Optional[Singularity]]: ...
