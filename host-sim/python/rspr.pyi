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
class DesignError(RsprError): ...

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

class Violation(TypedDict):
    guard: str
    subject: str
    value: float
    limit: float
    unit: str
    severity: str
    text: str

class Check(TypedDict):
    ok: bool
    severity: str
    violations: list[Violation]
    verdict: str

class Section(TypedDict):
    orientation: str
    rotation_deg: list[float]
    z_mm: float
    phi_deg: list[float]
    rho_max_mm: list[float]
    footprint_rays_inside: bool
    footprint_violation: Optional[str]
    footprint_inside: bool

class TaskBoxVerdict(TypedDict):
    inside: bool
    points: int
    spacing_mm: list[float]
    first_violation: Optional[str]
    orientation_violations: list[Optional[str]]

class Workspace(TypedDict):
    sections: list[Section]
    task_box: TaskBoxVerdict

class Readings(TypedDict):
    peak: float
    mean: float
    peak_to_peak: float

class GroupReadings(TypedDict):
    rspr: Readings
    rrps: Readings
    reduction: Readings

class Comparison(TypedDict):
    rspr_e_mm: float
    rrps_e_mm: float
    s: list[float]
    poses: list[list[float]]
    rspr_tau: list[Optional[list[float]]]
    rrps_tau: list[Optional[list[float]]]
    rspr_errors: list[Optional[str]]
    rrps_errors: list[Optional[str]]
    rspr_peaks: list[float]
    rrps_peaks: list[float]
    rotary_torque: GroupReadings
    leg_force: GroupReadings

class Candidate(TypedDict):
    dims_mm: dict[str, float]
    envelope_volume_cm3: float
    admissible: bool
    rejected: Optional[str]
    rank: Optional[int]
    parallel_inv_cond_min: Optional[float]
    serial_min: Optional[float]
    ranges: dict[str, list[float]]

Range = tuple[float, float, float]
"""(from, to, step), mm."""

def synth(
    kind: Literal["rspr", "usr"] = "rspr",
    dims: Optional[Union[Numbers, Rows]] = None,
    task: Optional[Union[str, PathLike[str]]] = None,
    e_mm: Optional[Range] = None,
    rb_mm: Optional[Range] = None,
    rp_mm: Optional[Range] = None,
    l1_mm: Optional[Range] = None,
    l2_mm: Optional[Range] = None,
    hc_mm: Optional[Range] = None,
    grid: Optional[tuple[int, int, int]] = None,
    jobs: int = 0,
) -> list[Candidate]: ...

class Robot:
    def __init__(self, kind: Literal["rspr", "usr"] = "rspr", limits: Optional[Union[str, PathLike[str]]] = None) -> None: ...
    @staticmethod
    def from_file(path: Union[str, PathLike[str]], limits: Optional[Union[str, PathLike[str]]] = None) -> Robot: ...
    @property
    def limits_source(self) -> str: ...
    @property
    def dims_mm(self) -> dict[str, float]: ...
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
    @overload
    def check(self, pose: Numbers, branch: int = 0, errors: Errors = "raise") -> Check: ...
    @overload
    def check(self, pose: Rows, branch: int = 0, errors: Errors = "raise") -> list[Optional[Check]]: ...
    @overload
    def admissible(self, pose: Numbers, branch: int = 0) -> Optional[str]: ...
    @overload
    def admissible(self, pose: Rows, branch: int = 0) -> list[Optional[str]]: ...
    def workspace(
        self,
        z_mm: Range = (-30.0, 30.0, 10.0),
        phi_step_deg: float = 5.0,
        step_mm: float = 1.0,
        tol_mm: float = 0.01,
        max_radius_mm: float = 150.0,
        box_mm: tuple[float, float, float] = (40.0, 40.0, 20.0),
        tilt_deg: float = 20.0,
        branch: int = 0,
    ) -> Workspace: ...
    def compare(
        self,
        e_mm: float = 0.0,
        rrps_e_mm: Optional[float] = None,
        samples: int = 101,
        wrench: Optional[Numbers] = None,
        branch: int = 0,
    ) -> Comparison: ...
